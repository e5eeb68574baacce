"""ArduSub's GUIDED mode on the built-in vehicle (4.5, and 4.7.2's acceleration targets): position targets in, the
mixer's six axes out.

Mirrored from ArduPilot's source (ArduSub 4.5):
- ArduSub/GCS_Mavlink.cpp, `GCS_MAVLINK_Sub::handle_message`, SET_POSITION_TARGET_LOCAL_NED: acted on only in GUIDED;
  frames LOCAL_NED (about the EKF origin: LOCAL_POSITION_NED's), LOCAL_OFFSET_NED (added to the current position),
  BODY_NED and BODY_OFFSET_NED (rotated by the heading, then added); any other frame is ignored. By type_mask:
  position + velocity (acceleration ignored) -> `guided_set_destination_posvel`, velocity only ->
  `guided_set_velocity`, position only -> `guided_set_destination`; any other combination is ignored. Yaw is used
  unless YAW_IGNORE (relative to the heading in BODY_OFFSET_NED).
- ArduSub/mode_guided.cpp: `ModeGuided::init` needs a position estimate (the bridge always has one) and starts by
  holding where the vehicle is (`guided_pos_control_start`: the stopping point, the heading held).
  `guided_posvel_control_run`: disarmed, nothing runs and the controllers restart; armed, the position target
  advances by the velocity target every loop, and after GUIDED_POSVEL_TIMEOUT_MS (3 s) without a new target the
  velocity target is zeroed, so the vehicle holds the last position target: no disarm, no mode change.
- ArduSub 4.7.2 (PR #33609, backported by #34298: Guided_PosVel became Guided_PosVelAccel): position + velocity +
  acceleration is accepted, the acceleration fed forward into the position controller and carried with the targets
  (the velocity target advances by it as the position target by the velocity); it is used only with both position and
  velocity, every other combination still needs the acceleration ignored. At the 3 s timeout the acceleration target
  is zeroed with the velocity (chosen: the PR's review leaves it open; the vehicle comes to a stop either way).
- libraries/AC_AttitudeControl/AC_PosControl.cpp, `update_xy_controller`: position error -> `sqrt_controller`
  (PSC_POSXY_P, limited by WPNAV_SPEED and WPNAV_ACCEL) + the velocity target (feed-forward) -> velocity PID
  (PSC_VELXY_P/I/D/IMAX, error and derivative filtered at FLTE/FLTD) -> acceleration, limited by ANGLE_MAX ->
  `accel_to_lean_angles` (forward and right accelerations in the heading's frame -> pitch, roll).
  `update_z_controller`: depth error -> `sqrt_controller` (PSC_POSZ_P, WPNAV_SPEED_UP/DN, WPNAV_ACCEL_Z) + velocity
  target -> P (PSC_VELZ_P) -> acceleration target -> PID on the measured vertical acceleration (PSC_ACCZ_*) x 0.001
  + hover throttle 0.5 (AP_Motors6DOF: throttle axis = 2 (throttle - 0.5)).
- ArduSub/Sub.cpp, `Sub::translate_pos_control_rp`: the lean angles are not flown (no lean on a sub): roll and -pitch
  become the lateral and forward axes, each as a share of ANGLE_MAX.
- AC_AttitudeControl: `input_euler_angle_roll_pitch_slew_yaw` with the heading target slewed at 60 deg/s
  (ArduSub's AUTO_YAW_SLEW_RATE); angle P (ATC_ANG_*_P) -> body rate target (yaw limited to ATC_RATE_Y_MAX) -> rate
  PID (ATC_RAT_*_P/I/D/IMAX) -> the roll, pitch and yaw axes; roll and pitch held level (the pilot's sticks, centred).
Left out (this is the structure and ArduSub's default gains, not a copy): the jerk-limited shaping of the target
(`shape_pos_vel_accel_xy`: the target is used as given), the attitude controller's input shaping and its rate
feed-forward of roll and pitch, the pilot's roll, pitch and yaw sticks in GUIDED, the waypoint navigator of the
position-only submode (a position-only target is held through the speed-limited sqrt controller), the vertical
acceleration from an IMU (here the rate of the estimate's vertical velocity).
Gains in ArduPilot's units (cm, cm/s, cm/s/s, throttle), read from the bridge's parameters every loop.
"""

from __future__ import annotations

import math

import numpy as np

from rov_mav.model.dynamics import rotation
from rov_mav.units import wrap_angle

FRAME_LOCAL_NED, FRAME_LOCAL_OFFSET_NED, FRAME_BODY_NED, FRAME_BODY_OFFSET_NED, FRAME_BODY_FRD = 1, 7, 8, 9, 12
BODY_FRAMES = frozenset({FRAME_BODY_NED, FRAME_BODY_OFFSET_NED, FRAME_BODY_FRD})
FRAMES = frozenset({FRAME_LOCAL_NED, FRAME_LOCAL_OFFSET_NED}) | BODY_FRAMES
# MAV_FRAME of SET_POSITION_TARGET_GLOBAL_INT -> the altitude's reference: the sea (AMSL), home, the terrain
GLOBAL_FRAMES = {0: "sea", 5: "sea", 3: "home", 6: "home", 10: "terrain", 11: "terrain"}
TERRAIN_REFUSAL = "Terrain data (rangefinder) not available"    # PR #27767, the first terrain target without one
POS_IGNORE, VEL_IGNORE, ACC_IGNORE, YAW_IGNORE = 0x007, 0x038, 0x1C0, 0x400   # MAVLINK_SET_POS_TYPE_MASK_*
Z_IGNORE, YAW_RATE_IGNORE = 0x004, 0x800
POSVEL, VELOCITY, WAYPOINT = "posvel", "velocity", "waypoint"    # the sub-modes a target selects
POSVEL_TIMEOUT = 3.0            # s: GUIDED_POSVEL_TIMEOUT_MS
YAW_SLEW = math.radians(60.0)   # rad/s: AUTO_YAW_SLEW_RATE
GRAVITY_CMSS = 980.665


def sqrt_controller(error: float, p: float, accel_max: float, dt: float) -> float:
    """AP_Math/control.cpp `sqrt_controller`: P near the target, the square root of the braking distance beyond
    accel_max / p^2, never more than the error covered in one step."""
    if accel_max <= 0:
        correction = error * p
    elif p == 0:
        correction = math.copysign(math.sqrt(2.0 * accel_max * abs(error)), error)
    else:
        linear = accel_max / (p * p)
        if abs(error) > linear:
            correction = math.copysign(math.sqrt(2.0 * accel_max * (abs(error) - 0.5 * linear)), error)
        else:
            correction = error * p
    if dt > 0:
        correction = min(max(correction, -abs(error) / dt), abs(error) / dt)
    return correction


def takes_terrain(type_mask: int) -> bool:
    """A terrain target's type_mask PR #27767 takes: position and velocity used, the acceleration ignored (a
    position alone, or an acceleration, and it is dropped)."""
    return not type_mask & (POS_IGNORE | VEL_IGNORE) and type_mask & ACC_IGNORE == ACC_IGNORE


def _alpha(hz: float, dt: float) -> float:
    """A first-order low-pass filter's step gain at cut-off `hz` (0: no filter), as AC_PID's `get_filt_alpha`."""
    return 1.0 if hz <= 0 else dt / (dt + 1.0 / (2.0 * math.pi * hz))


class Pid:
    """AC_PID's `update_all` (one axis; the 2-D velocity PID is two of these sharing a limit): error filtered at
    `flte`, derivative at `fltd`, integrator limited to imax."""

    def __init__(self):
        self.reset()

    def reset(self) -> None:
        self.error: float | None = None
        self.derivative = 0.0
        self.integrator = 0.0

    def update(self, error: float, dt: float, kp: float, ki: float, kd: float, imax: float, flte: float = 0.0,
               fltd: float = 0.0) -> float:
        if self.error is None or dt <= 0:
            self.error = error
            self.derivative = 0.0
        else:
            last = self.error
            self.error += (error - self.error) * _alpha(flte, dt)
            self.derivative += ((self.error - last) / dt - self.derivative) * _alpha(fltd, dt)
        self.integrator = min(max(self.integrator + self.error * ki * dt, -imax), imax)
        return kp * self.error + self.integrator + kd * self.derivative


class Guided:
    """The GUIDED mode's target and controllers. `target(...)` takes a SET_POSITION_TARGET_LOCAL_NED, `axes(...)` is
    one main-loop pass; `reset()` when the mode is entered or the vehicle disarmed."""

    def __init__(self, accel_targets: bool = False):
        self.accel_targets = accel_targets          # 4.7.2: Guided_PosVelAccel
        self.reset()

    def reset(self) -> None:
        """Hold where the vehicle is at the next pass (its position, depth and heading)."""
        self.submode = WAYPOINT                     # `ModeGuided::init`: the stopping point, by the waypoint navigator
        self.position: np.ndarray | None = None     # NED m, the position target
        self.velocity = np.zeros(3)                 # NED m/s
        self.acceleration = np.zeros(3)             # NED m/s/s (4.7.2)
        self.heading: float | None = None           # rad, the commanded heading
        self.yaw_slew = YAW_SLEW                    # rad/s the heading target turns at towards it
        self.yaw_rate: float | None = None          # rad/s, a yaw-rate-only target (no heading)
        self.heading_target: float | None = None    # rad, the slewed heading flown
        self.updated = -math.inf                    # s, when the last target came
        self.vel_xy = (Pid(), Pid())
        self.accel_z = Pid()
        self.rates = (Pid(), Pid(), Pid())
        self._climb: float | None = None            # cm/s, last measured climb rate
        self.terrain_range: float | None = None     # m: a terrain target's rangefinder distance (PR #27767)

    def target(self, frame: int, type_mask: int, position, velocity, yaw: float, state, t: float,
               acceleration=(0.0, 0.0, 0.0), yaw_rate: float = 0.0) -> bool:
        """A SET_POSITION_TARGET_LOCAL_NED's fields (NED m, m/s, m/s/s, rad, rad/s) with the vehicle's (eta, nu);
        False when ArduSub would ignore it (frame or type_mask). Body frames (BODY_NED, BODY_OFFSET_NED, BODY_FRD) are
        rotated by the heading only and, like LOCAL_OFFSET_NED, added to the current position, depth included; the
        yaw is relative in BODY_OFFSET_NED only (`GCS_MAVLINK_Sub::handle_message`)."""
        if frame not in FRAMES or state is None:
            return False
        eta = state[0]
        c, s = math.cos(eta[5]), math.sin(eta[5])
        body = frame in BODY_FRAMES

        def rotated(v):
            v = np.asarray(v, dtype=float)
            return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]]) if body else v

        pos = None if type_mask & POS_IGNORE else rotated(position) + (eta[:3] if frame != FRAME_LOCAL_NED else 0.0)
        if not self._set(type_mask, pos, rotated(velocity), rotated(acceleration), eta, t):
            return False
        self.terrain_range = None
        self._yaw(type_mask, yaw + (eta[5] if frame == FRAME_BODY_OFFSET_NED else 0.0), yaw_rate)
        return True

    def global_target(self, type_mask: int, position: np.ndarray | None, velocity, state, t: float) -> bool:
        """A SET_POSITION_TARGET_GLOBAL_INT's, its position already made NED m from the EKF origin (None: it could not
        be, or is ignored) and its velocity NED m/s; its yaw and yaw rate are not used (ArduSub leaves them for
        future use). False when ArduSub would ignore it."""
        if state is None or (position is None and not type_mask & POS_IGNORE):
            return False
        self.terrain_range = None
        return self._set(type_mask, position, np.asarray(velocity, dtype=float), np.zeros(3), state[0], t)

    def terrain_target(self, type_mask: int, north_east, distance: float, velocity, terrain_depth: float,
                       state, t: float) -> bool:
        """PR #27767's ABOVE_TERRAIN position-velocity target (`guided_set_destination_posvel` with ABOVE_TERRAIN):
        north and east from the EKF origin, `distance` the rangefinder range to hold (m) from the bottom's depth as
        the rangefinder last measured it, the velocity NED m/s; its type_mask as `takes_terrain` says (the caller
        refuses the first without a healthy rangefinder). False when it is not taken."""
        if state is None or not takes_terrain(type_mask):
            return False
        position = np.array([north_east[0], north_east[1], terrain_depth - distance])
        self._set(type_mask, position, np.asarray(velocity, dtype=float), np.zeros(3), state[0], t)
        self.terrain_range = distance
        return True

    def track(self, position, velocity, t: float, terrain_range: float | None = None) -> None:
        """A waypoint navigator's target, every loop (AUTO's legs, `sim_bridge.modes.auto`, as AC_WPNav hands
        AC_PosControl its position and velocity): position NED m (None: the target kept), velocity NED m/s fed
        forward; with `terrain_range` the depth follows the bottom `axes` is given, as a terrain target's does."""
        if position is not None:
            self.position = np.array(position, dtype=float)
        self.velocity = np.asarray(velocity, dtype=float)
        self.acceleration = np.zeros(3)
        self.submode = POSVEL
        self.updated = t
        self.terrain_range = terrain_range

    def _set(self, type_mask: int, position, velocity, acceleration, eta, t: float) -> bool:
        """The sub-mode the type_mask selects (`guided_set_destination_posvel`, `guided_set_velocity`,
        `guided_set_destination`), with its targets; False for a combination ArduSub drops."""
        use_pos, use_vel = not type_mask & POS_IGNORE, not type_mask & VEL_IGNORE
        use_acc = not type_mask & ACC_IGNORE
        if use_acc and not (self.accel_targets and use_pos and use_vel) or not (use_pos or use_vel):
            return False
        if use_pos:
            self.position = np.asarray(position, dtype=float)
        elif self.position is None or self.submode != VELOCITY:
            self.position = np.array(eta[:3], dtype=float)
        self.submode = POSVEL if use_pos and use_vel else VELOCITY if use_vel else WAYPOINT
        self.velocity = velocity if use_vel else np.zeros(3)
        self.acceleration = acceleration if use_acc else np.zeros(3)
        self.updated = t
        return True

    def _yaw(self, type_mask: int, yaw: float, yaw_rate: float) -> None:
        """`guided_set_yaw_state`: a heading, turned to at AUTO_YAW_SLEW_RATE or, with a rate, at min(rate, that); a
        rate alone turns at it (at most AUTO_YAW_SLEW_RATE); neither: the heading held as it was."""
        use_yaw, use_rate = not type_mask & YAW_IGNORE, not type_mask & YAW_RATE_IGNORE
        if use_yaw:
            self.heading = float(wrap_angle(yaw))
            self.yaw_slew = min(abs(yaw_rate), YAW_SLEW) if use_rate else YAW_SLEW
            self.yaw_rate = None
        elif use_rate:
            self.yaw_rate = min(max(yaw_rate, -YAW_SLEW), YAW_SLEW)

    def axes(self, params, eta: np.ndarray, nu: np.ndarray, t: float, dt: float,
             terrain_depth: float | None = None) -> list[float]:
        """The mixer's (roll, pitch, yaw, throttle, forward, lateral) in [-1, 1] for one loop of dt s at time t;
        `terrain_depth`: the bottom's depth while the rangefinder is healthy (a terrain target follows it, and holds
        the last one while it is not: PR #27767's `guided_posvel_terrain_control_run`)."""
        if self.position is None:
            self.position = np.array(eta[:3], dtype=float)
        if self.terrain_range is not None and terrain_depth is not None:
            self.position[2] = terrain_depth - self.terrain_range - self.velocity[2] * dt
        if self.heading is None:
            self.heading = float(eta[5])
        if t - self.updated > POSVEL_TIMEOUT and self.submode != WAYPOINT:
            self.velocity = np.zeros(3)
            self.acceleration = np.zeros(3)
        if self.submode == VELOCITY:          # `NE_stop_pos_stabilisation`: no horizontal position is held
            self.position[:2] = eta[:2]
        self.position = self.position + self.velocity * dt + 0.5 * self.acceleration * dt * dt
        self.velocity = self.velocity + self.acceleration * dt
        v_ned = rotation(eta) @ np.asarray(nu[:3], dtype=float)
        forward, lateral = self._horizontal(params, eta, v_ned, dt)
        throttle = self._vertical(params, eta, v_ned, dt)
        roll, pitch, yaw = self._attitude(params, eta, nu, dt)
        return [min(max(a, -1.0), 1.0) for a in (roll, pitch, yaw, throttle, forward, lateral)]

    def _horizontal(self, p, eta, v_ned, dt) -> tuple[float, float]:
        """AC_PosControl::update_xy_controller and Sub::translate_pos_control_rp, in cm (floats: it runs every
        loop)."""
        error_n, error_e = (self.position[0] - eta[0]) * 100.0, (self.position[1] - eta[1]) * 100.0
        distance = math.hypot(error_n, error_e)
        speed = min(sqrt_controller(distance, p["PSC_POSXY_P"], p["WPNAV_ACCEL"], dt), p["WPNAV_SPEED"])
        scale = speed / distance if distance > 0 else 0.0
        gains = (dt, p["PSC_VELXY_P"], p["PSC_VELXY_I"], p["PSC_VELXY_D"], p["PSC_VELXY_IMAX"], p["PSC_VELXY_FLTE"],
                 p["PSC_VELXY_FLTD"])
        pid_n, pid_e = self.vel_xy
        accel_n = pid_n.update(error_n * scale + (self.velocity[0] - v_ned[0]) * 100.0, *gains) \
            + self.acceleration[0] * 100.0
        accel_e = pid_e.update(error_e * scale + (self.velocity[1] - v_ned[1]) * 100.0, *gains) \
            + self.acceleration[1] * 100.0
        angle_max = max(math.radians(p["ANGLE_MAX"] / 100.0), 1e-6)   # (0 would divide by zero: no lean)
        accel_max = GRAVITY_CMSS * math.tan(angle_max)
        norm = math.hypot(accel_n, accel_e)
        if norm > accel_max:
            accel_n, accel_e = accel_n * accel_max / norm, accel_e * accel_max / norm
        c, s = math.cos(eta[5]), math.sin(eta[5])
        accel_forward = c * accel_n + s * accel_e
        accel_right = -s * accel_n + c * accel_e
        pitch = math.atan(-accel_forward / GRAVITY_CMSS)
        roll = math.atan(accel_right * math.cos(pitch) / GRAVITY_CMSS)
        return (min(max(-pitch / angle_max, -1.0), 1.0), min(max(roll / angle_max, -1.0), 1.0))

    def _vertical(self, p, eta, v_ned, dt) -> float:
        """AC_PosControl::update_z_controller, up positive in cm: the throttle axis."""
        error = (eta[2] - self.position[2]) * 100.0                  # target altitude - altitude
        accel_up = p["WPNAV_ACCEL_Z"]
        climb = sqrt_controller(error, p["PSC_POSZ_P"], accel_up, dt)
        climb = min(max(climb, -p["WPNAV_SPEED_DN"]), p["WPNAV_SPEED_UP"]) - self.velocity[2] * 100.0
        measured = -v_ned[2] * 100.0
        accel_target = p["PSC_VELZ_P"] * (climb - measured) - self.acceleration[2] * 100.0
        accel_measured = 0.0 if self._climb is None or dt <= 0 else (measured - self._climb) / dt
        self._climb = measured
        thrust = self.accel_z.update(accel_target - accel_measured, dt, p["PSC_ACCZ_P"], p["PSC_ACCZ_I"],
                                     p["PSC_ACCZ_D"], p["PSC_ACCZ_IMAX"], p["PSC_ACCZ_FLTE"]) * 0.001
        return 2.0 * thrust                    # AP_Motors6DOF: 2 (throttle - hover), hover 0.5

    def _attitude(self, p, eta, nu, dt) -> tuple[float, float, float]:
        """Level roll and pitch, the slewed heading: angle P -> rate target -> rate PID, per axis."""
        if self.heading_target is None:
            self.heading_target = float(eta[5])
        if self.yaw_rate is not None:         # AUTO_YAW_RATE: the heading target turns at the rate
            self.heading = float(wrap_angle(self.heading_target + self.yaw_rate * dt))
        step = float(wrap_angle(self.heading - self.heading_target))
        step = min(max(step, -self.yaw_slew * dt), self.yaw_slew * dt)
        self.heading_target = float(wrap_angle(self.heading_target + step))
        yaw_ff = step / dt if dt > 0 else 0.0
        rate_max = math.radians(p["ATC_RATE_Y_MAX"]) if p["ATC_RATE_Y_MAX"] > 0 else math.inf
        targets = (p["ATC_ANG_RLL_P"] * -eta[3], p["ATC_ANG_PIT_P"] * -eta[4],
                   min(max(p["ATC_ANG_YAW_P"] * float(wrap_angle(self.heading_target - eta[5])) + yaw_ff,
                           -rate_max), rate_max))
        out = []
        for pid, axis, target, rate in zip(self.rates, ("RLL", "PIT", "YAW"), targets, nu[3:6]):
            out.append(pid.update(target - rate, dt, p[f"ATC_RAT_{axis}_P"], p[f"ATC_RAT_{axis}_I"],
                                  p[f"ATC_RAT_{axis}_D"], p[f"ATC_RAT_{axis}_IMAX"]))
        return tuple(out)
