"""The emulated ArduSub vehicle logic: modes, arming, RC input, failsafes and servo output routing.

Pure: no I/O and no wall clock; every method takes the simulated time `t` in seconds. What it has to tell the
ground station (STATUSTEXT) is queued in `texts` for the caller to send.

Behaviour reproduced on purpose, hazards included (reference: bluerov2-ardusub.md):
- RC overrides only from a GCS sysid (`GCS::sysid_is_gcs`: MAV_GCS_SYSID, or on 4.7 the range up to
  MAV_GCS_SYSID_HI, `Params.is_gcs`); they count as GCS heartbeats and as pilot input.
- MANUAL_CONTROL (ArduSub/GCS_MAVLink_Sub.cpp, `GCS_MAVLINK_Sub::handle_message`): only from a GCS sysid and with
  `target` equal to this vehicle's sysid (0 is not accepted); its axes become overrides of channels 1-11 on 4.5, 1-8
  on 4.7 (`joystick`) with the same expiry, and it counts as pilot input and as a GCS heartbeat. Its buttons arm,
  disarm and change modes by BTNn_FUNCTION (`sim_bridge.autopilot.buttons`, Sub's defaults: 1 MANUAL, 2 ALT_HOLD, 3
  STABILIZE,
  4 disarm, 5 shift, 6 arm); the other functions (lights, mount, gains, trims) do nothing here.
- The software safety switch (a mode change with base_mode 128, custom mode 1 on, 0 off): while on, every output reads
  0 and sends no pulse, armed or not (measured on ArduSub 4.5.3 SITL). A BlueROV2 boots with it off.
- The vehicle's own sysid is fixed at boot (ArduPilot applies SYSID_THISMAV / MAV_SYSID on reboot: measured).
- SERVOn_FUNCTION 51..66 (RCIN1..16) passes RC input n straight to output n, whether armed or not, without motor
  directions; with no RC receiver the output keeps its last value after the override ends.
- The frame is FRAME_CONFIG as it was at boot (`Sub::init_rc_out`; `rov_mav.model.frames`): its motors and their
  mixer (`sim_bridge.autopilot.mixer`). SERVOn_FUNCTION 33..40 (motors 1..8) come from that mixer of the pilot
  channels, only
  when armed (1500 us when disarmed); an output assigned a motor the frame does not have sends no pulse (nothing
  writes its function), limited to MOT_PWM_MIN..MAX, or RC3_MIN..MAX when those two are invalid
  (AP_MotorsMulticopter::check_mot_pwm_params); every output fits uint16 as the hardware register does; in STABILIZE,
  ACRO, ALT_HOLD and POSHOLD through the holds of `stabilize` first, in GUIDED through `guided`'s position
  controller (its targets from SET_POSITION_TARGET_LOCAL_NED), on the state estimate passed to `update`; SURFACE as
  `sim_bridge.modes.surface`; AUTO flies the stored mission (`mission`, the items as `sim_bridge.gcs.missions`
  keeps them) through `sim_bridge.modes.auto`, armed or not, with GUIDED's controller. Mode changes pass
  `Sub::set_mode`'s gates (`sim_bridge.modes.gates`): GUIDED, POSHOLD and AUTO need `Sub::position_ok` (the EKF's,
  from `sensors`, and no EKF failsafe), ALT_HOLD a working depth sensor, AUTO a mission; leaving AUTO stops the
  mission (`Sub::exit_mode`).
- The failsafes (pilot input, GCS, leak, battery, EKF, depth sensor): `sim_bridge.autopilot.failsafes`, as
  ArduSub/failsafe.cpp keeps them, on the `sensors` given to `update`.
- HEARTBEAT system_status (`GCS_MAVLINK_Sub::vehicle_system_status`): CRITICAL while a failsafe of
  `any_failsafe_triggered` is set, else ACTIVE armed, BOOT until initialised (`ap.initialised`), STANDBY.
- Motor test (MAV_CMD_DO_MOTOR_TEST, ArduSub/motors.cpp `handle_do_motor_test`, `init_motor_test`,
  `verify_motor_test`; AP_MotorsMatrix `output_test_num`): from any sysid; needs the vehicle armed, no failed start
  in the last 2 s (nor in the first 2 s after boot) and no timeout in the last 10 s; test type BOARD (2) only; param1
  is the 0-based index of a motor of the frame, the PWM raw (no MOT_n_DIRECTION, no MOT_PWM_MIN..MAX). While it runs
  the motors show only the test PWMs (1500 until commanded) instead of the mixer (`Sub::motors_output` calls only
  `verify_motor_test`); 0.5 s without a command ends it and disarms. A disarm does not end it, and nothing writes the
  outputs then: the last test PWMs stay on the thrusters, every further command (refused: `output_test_num` needs
  the vehicle armed) is still stamped as the test's last (`handle_do_motor_test` stamps before anything else), and
  only the timeout 0.5 s after the last command brings the motors back to neutral.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from rov_mav.model.frames import MAX_MOTORS, frame_of
from rov_mav.units import north_east
from sim_bridge.autopilot import arming, buttons, joystick, mixer
from sim_bridge.autopilot.failsafes import Failsafes, Readings
from sim_bridge.autopilot.params import Params
from sim_bridge.autopilot.rc import RCInput
from sim_bridge.hardware.numeric import f32, float_to_int, is_equal
from sim_bridge.modes import gates, guided, surface
from sim_bridge.modes.auto import Auto
from sim_bridge.modes.gates import GUIDED_FLAG_MODES, MODE_NAMES, MODES, SUPPORTED_MODES  # noqa: F401 (re-exported)
from sim_bridge.modes.guided import Guided
from sim_bridge.modes.stabilize import ALT_HOLD, ASSISTED, Holds
from sim_bridge.modes.terrain import Rangefinder, Surftrak

MAV_RESULT_ACCEPTED, MAV_RESULT_DENIED, MAV_RESULT_UNSUPPORTED, MAV_RESULT_FAILED = 0, 2, 3, 4
MAV_STATE_BOOT, MAV_STATE_STANDBY, MAV_STATE_ACTIVE, MAV_STATE_CRITICAL = 1, 3, 4, 5
MAV_SEVERITY_CRITICAL, MAV_SEVERITY_WARNING, MAV_SEVERITY_INFO = 2, 4, 6
RCIN1, RCIN16 = 51, 66
MOTOR1 = 33                     # SERVOn_FUNCTION of motor 1 (`rov_mav.model.frames`)
SERVOS = 16
# Pilot axis of each RC channel 1..6 in the mixer's order (roll, pitch, yaw, throttle, forward, lateral).
PILOT_CHANNEL_OF_AXIS = (1, 0, 3, 2, 4, 5)
_RC_RANGE = [(f"RC{ch + 1}_MIN", f"RC{ch + 1}_TRIM", f"RC{ch + 1}_MAX") for ch in PILOT_CHANNEL_OF_AXIS]
_MOTOR_DIRECTION = [f"MOT_{i}_DIRECTION" for i in range(1, MAX_MOTORS + 1)]
_SERVO_FUNCTION = [f"SERVO{n}_FUNCTION" for n in range(1, SERVOS + 1)]
NEUTRAL = 1500
UINT16_MAX = 65535
MOTOR_TEST_THROTTLE_PERCENT, MOTOR_TEST_THROTTLE_PWM, MOTOR_TEST_THROTTLE_PILOT = 0, 1, 2
MOTOR_TEST_ORDER_BOARD = 2
MOTOR_TEST_TIMEOUT = 0.5        # s without a DO_MOTOR_TEST that ends the test
MOTOR_TEST_RETRY = 2.0          # s after a failed start (and after boot) before the next start is tried
MOTOR_TEST_COOLDOWN = 10.0      # s after a timeout before a new test may start


class ArduSub:
    """State of one emulated ArduSub vehicle; drive it with the handlers and `update(t)`."""

    def __init__(self, params: Params, t: float = 0.0, origin: tuple[float, float, float] | None = None,
                 mission: Callable[[], list] | None = None):
        self.params = params
        self.mission = mission or list                  # the stored mission's items, home's slot first
        self.sysid = params.sysid & 0xFF                # `mavlink_system.sysid` is a uint8_t
        self.frame = frame_of(int(params["FRAME_CONFIG"]))   # fixed at boot
        self.origin = origin                            # the EKF origin (lat deg, lon deg, alt m); home is it
        self._neutral = np.full(self.frame.motors, NEUTRAL, dtype=np.int32)
        self.joystick_gain = joystick.joystick_gain(params["JS_GAIN_DEFAULT"], params["JS_GAIN_MIN"],
                                                    params["JS_GAIN_MAX"], params["JS_GAIN_STEPS"])
        self._lights = (int(params["RC9_MIN"]), int(params["RC10_MIN"]))
        self.rc = RCInput(params.firmware)
        self.mode = MODES["MANUAL"]
        self.armed = False
        self.safety_on = False            # no safety switch on a BlueROV2: outputs flow from boot
        self.texts: list[tuple[int, str]] = []
        self._routing_version = -1
        self._mix_key: tuple | None = None
        self._directions: list[float] = []
        self._directions_version = -1
        self.holds = Holds()
        self.guided = Guided(accel_targets=params.firmware == "4.7")
        self._state: tuple[np.ndarray, np.ndarray] | None = None   # the last estimate `update` was given
        self._held: np.ndarray | None = None          # motor PWM from the assisted modes' holds, this pass
        self.motor_testing = False
        self._test_pwm = self._neutral
        self._test_seen = t                           # the last DO_MOTOR_TEST
        self._test_start_failed = t                   # ArduSub's static starts at 0: boot
        self._test_timed_out: float | None = None
        self._t = t
        self.initialised = True                       # `ap.initialised`: the bridge clears it while booting
        self.sensors = Readings()
        self.position_ok_flags = (True, True)         # the EKF's (armed, disarmed) position_ok
        self.failsafes = Failsafes(t)
        self.surface = surface.SurfaceDetector()
        self._nobaro = False                          # SURFACE entered without a depth sensor (4.7)
        self.rangefinder = Rangefinder(params)        # `sim_bridge.modes.terrain`: set up at boot
        self.surftrak = Surftrak()
        self.auto = Auto(self.guided)                 # `sim_bridge.modes.auto`: AUTO's mission (AP_Mission)

    # -- inputs ----------------------------------------------------------------------------------------------

    def gcs_heartbeat(self, sysid: int, t: float) -> None:
        """A HEARTBEAT from `sysid`: refreshes the GCS failsafe if it is a GCS sysid."""
        if self.params.is_gcs(sysid):
            self.failsafes.heard_gcs(t)

    def rc_override(self, sysid: int, values: list[int], t: float) -> bool:
        """RC_CHANNELS_OVERRIDE's 18 channel fields from `sysid`; False (ignored) unless it is a GCS sysid."""
        if not self.params.is_gcs(sysid):
            return False
        self.rc.apply_message(values, t)
        self.failsafes.heard_pilot(t)
        return True

    def manual_control(self, sysid: int, target: int, axes: tuple[int, ...], t: float, pressed: int = 0) -> bool:
        """MANUAL_CONTROL's (x, y, z, r, s, t) and 32 buttons from `sysid` to `target`; False (ignored) unless from
        a GCS sysid and aimed at this vehicle. The buttons act as `sim_bridge.autopilot.buttons` says, after the
        axes."""
        if not self.params.is_gcs(sysid) or target != self.sysid:
            return False
        values = joystick.rc_channels(*axes, gain=self.joystick_gain, throttle_gain=self.params["JS_THR_GAIN"],
                                      lights=self._lights, firmware=self.params.firmware)
        for ch, value in enumerate(values):
            self.rc.set_override(ch, value, t)
        for action, value in buttons.press(self.params, pressed):
            if action == "mode":
                self.set_mode(value)
            else:
                self.arm(not self.armed if action == "toggle" else bool(value))
        self.failsafes.heard_pilot(t)
        return True

    def arm(self, arm: bool, checks: bool = True) -> int:
        """Arm or disarm: MAV_RESULT. Arming first needs the throttle centred (4.7, forced or not), then passes the
        arming checks unless `checks` is False (`sim_bridge.autopilot.arming`): each failure sent as CRITICAL "Arm:
        ...", and
        FAILED."""
        if arm and not self.armed and (refusal := arming.throttle_refusal(self.params, int(self.rc.radio_in[2]))):
            self.texts.append((MAV_SEVERITY_CRITICAL, refusal))
            return MAV_RESULT_FAILED
        if arm and not self.armed and checks:
            if failed := arming.failures(self.params, self.sensors):
                self.texts += [(MAV_SEVERITY_CRITICAL, f"Arm: {text}") for text in failed]
                return MAV_RESULT_FAILED
            if arming.all_off(self.params):
                self.texts.append((MAV_SEVERITY_WARNING, arming.CHECKS_OFF_WARNING))
        if arm != self.armed:
            self.holds.reset()
            self.guided.reset()
            self.surftrak.reset()
            self._held = None
        self.armed = arm
        return MAV_RESULT_ACCEPTED

    def set_mode(self, custom_mode: int) -> bool:
        """Change mode (ArduSub/mode.cpp, `Sub::set_mode`); False and its warnings when refused
        (`sim_bridge.modes.gates`)."""
        if custom_mode == self.mode:
            return True
        depth_present, depth_failsafe = self.sensors.depth_present, self.failsafes.depth
        refused = gates.refusal(custom_mode, self.params.firmware, self.position_ok(), depth_present, depth_failsafe,
                                mission_present=len(self.mission()) > 1)
        if refused:
            self.texts += [(MAV_SEVERITY_WARNING, text) for text in refused]
            return False
        if custom_mode == MODES["SURFACE"]:
            self._nobaro = gates.barometer_refusal(depth_present, depth_failsafe) is not None
        previous = self.mode
        if custom_mode != self.mode:
            self.holds.reset()
            self.guided.reset()
            self._held = None
        if custom_mode == MODES["AUTO"]:                  # `ModeAuto::init`, before the mode is AUTO
            self.auto.enter(self, self._state, self._t)
        if previous == MODES["AUTO"]:
            self.auto.exit()
        self.mode = custom_mode
        if custom_mode == MODES["SURFTRAK"]:
            depth = float(self._state[0][2]) if self._state is not None else 0.0
            self.surftrak.enter(self.rangefinder, depth, self._t, self.params, self.texts)
        return True

    def motor_test(self, motor: float, throttle_type: float, throttle: float, test_type: int, t: float) -> int:
        """MAV_CMD_DO_MOTOR_TEST as a COMMAND_INT (`Sub::handle_do_motor_test`): param1 the motor's 0-based index,
        param2 the throttle type, param3 the throttle, y the test type; MAV_RESULT. Cast as ArduSub casts them."""
        self._test_seen = t
        if not self.motor_testing:
            if t <= self._test_start_failed + MOTOR_TEST_RETRY:
                return MAV_RESULT_FAILED
            if not self._init_motor_test(t):
                self.texts.append((MAV_SEVERITY_WARNING, "motor test initialization failed!"))
                self._test_start_failed = t
                return MAV_RESULT_FAILED
        test_type &= 0xFFFFFFFF                                   # uint32_t
        if test_type != MOTOR_TEST_ORDER_BOARD:
            self.texts.append((MAV_SEVERITY_WARNING, f"bad test type {test_type:.2f}"))
            return MAV_RESULT_FAILED
        if is_equal(throttle_type, MOTOR_TEST_THROTTLE_PILOT):
            self.texts.append((MAV_SEVERITY_WARNING, f"bad throttle type {throttle_type:.2f}"))
            return MAV_RESULT_FAILED
        if is_equal(throttle_type, MOTOR_TEST_THROTTLE_PWM):
            pwm = throttle
        elif is_equal(throttle_type, MOTOR_TEST_THROTTLE_PERCENT):
            pwm = self._percent_pwm(throttle)
        else:
            return MAV_RESULT_FAILED
        ok = self._output_test_num(float_to_int(motor, 8, signed=False), float_to_int(pwm, 16))
        return MAV_RESULT_ACCEPTED if ok else MAV_RESULT_FAILED

    def _init_motor_test(self, t: float) -> bool:
        """`Sub::init_motor_test`: refused in the cooldown after a timeout or when disarmed, else all motors 1500."""
        if self._test_timed_out is not None and t < self._test_timed_out + MOTOR_TEST_COOLDOWN:
            self.texts.append((MAV_SEVERITY_CRITICAL, "10 second cooldown required after motor test"))
            return False
        if not self.armed:
            self.texts.append((MAV_SEVERITY_WARNING, "Arm motors before testing motors."))
            return False
        self._test_pwm = self._neutral.copy()
        self.motor_testing = True
        return True

    def _percent_pwm(self, percent: float) -> float:
        """0..100 % (NaN: 50, as AP_Math's constrain) onto RC3_MIN..MAX in float32, as ArduSub computes it."""
        percent = 50.0 if np.isnan(percent) else min(max(percent, 0.0), 100.0)
        low, high = int(self.params["RC3_MIN"]), int(self.params["RC3_MAX"])
        return f32(low + f32(f32(f32(percent) * f32(0.01)) * (high - low)))

    def _output_test_num(self, motor: int, pwm: int) -> bool:
        """`AP_MotorsMatrix::output_test_num`: the int16 PWM written raw (as the uint16 of `rc_write`) to a motor
        the frame has, only when armed."""
        if not self.armed or motor >= self.frame.motors:
            return False
        self._test_pwm[motor] = pwm & UINT16_MAX
        return True

    def set_safety(self, on: bool) -> None:
        """The software safety switch (`hal.rcout->force_safety_on/off`): while on, no output sends a pulse."""
        self.safety_on = on

    # -- time ------------------------------------------------------------------------------------------------

    def position_ok(self) -> bool:
        """`Sub::position_ok`: no EKF failsafe, and the EKF's position (absolute when armed, predicted when not)."""
        return not self.failsafes.ekf and self.position_ok_flags[0 if self.armed else 1]

    def update(self, t: float, state: tuple[np.ndarray, np.ndarray] | None = None,
               sensors: Readings | None = None) -> None:
        """One main-loop pass at time t: RC input, the failsafes (on the latest `sensors` given), then the assisted
        modes' holds on `state`, the attitude and position estimate (eta, nu)."""
        dt, self._t = t - self._t, t
        self.rc.update(t, self.params["RC_OVERRIDE_TIME"])
        if sensors is not None:
            self.sensors = sensors
        self.failsafes.update(self, t, self.sensors)
        self._verify_motor_test(t)
        self._held = None
        self._state = state
        depth_ok = self.sensors.depth_present and not self.failsafes.depth
        at_surface = self.surface.update(self.armed, float(state[0][2]) if depth_ok and state else None, self.params)
        if state is not None:
            self.rangefinder.update(t, float(state[0][2]), self.params)
        if self.mode == MODES["AUTO"] and state is not None:      # the mission runs disarmed too
            axes = self.auto.run(self, state, t, dt)
            if axes is not None and self.armed and self.mode == MODES["AUTO"]:
                self._held = mixer.to_pwm(self._mix(axes), *self._pwm_range())
            return
        if not self.armed or state is None:
            return
        if self.mode == MODES["SURFACE"] and at_surface and not self._nobaro:
            self.set_mode(MODES["ALT_HOLD"])                  # ModeReason::SURFACE_COMPLETE
        if self.mode in ASSISTED or self.mode == MODES["SURFTRAK"]:
            floor = surface.surface_depth(self.params) if at_surface else None
            pilot = self.pilot_axes()
            mode = self.mode
            if mode == MODES["SURFTRAK"]:                 # ALT_HOLD with its depth target set by the range held
                self.surftrak.run(self.holds, float(pilot[3]), float(state[0][2]), at_surface, self.rangefinder, t,
                                  dt, self.params, self.texts)
                mode = ALT_HOLD
            axes = self.holds.axes(mode, pilot, *state, dt, climb=surface.climb_rate(self.params),
                                   min_depth=floor, position_ok=self.position_ok())
            if self.mode == MODES["SURFACE"] and self._nobaro:
                axes[3] = surface.nobaro_throttle(self.params)
        elif self.mode == MODES["GUIDED"]:
            terrain = self.rangefinder.terrain_depth if self.rangefinder.alt_ok(t) else None
            axes = self.guided.axes(self.params.guided_gains(), *state, t, dt, terrain_depth=terrain)
        else:
            return
        self._held = mixer.to_pwm(self._mix(axes), *self._pwm_range())

    def position_target(self, frame: int, type_mask: int, position, velocity, yaw: float, t: float,
                        acceleration=(0.0, 0.0, 0.0), yaw_rate: float = 0.0) -> bool:
        """SET_POSITION_TARGET_LOCAL_NED's fields: a GUIDED target (`sim_bridge.modes.guided`); False (ignored)
        outside
        GUIDED or when ArduSub would ignore it."""
        if self.mode != MODES["GUIDED"]:
            return False
        return self.guided.target(frame, type_mask, position, velocity, yaw, self._state, t, acceleration, yaw_rate)

    def position_target_global(self, frame: int, type_mask: int, lat: float, lon: float, alt: float, velocity,
                               t: float) -> bool:
        """SET_POSITION_TARGET_GLOBAL_INT's fields (deg, m, NED m/s) as `GCS_MAVLINK_Sub::handle_message` takes them:
        in ALT_HOLD its altitude (m above the EKF origin, whatever the frame) becomes the depth target unless z is
        ignored; in GUIDED a target (`sim_bridge.modes.guided`), its position from the EKF origin by the frame's
        altitude
        reference (`Location::get_vector_from_origin_NEU`): above the sea, or home (the origin here); above the
        terrain (frames 10 and 11), as PR #27767 takes it (closed unmerged; ArduSub 4.7.2 drops such a target
        underwater, having no terrain database): a position-velocity target whose altitude is the rangefinder range
        to hold (`sim_bridge.modes.guided.Guided.terrain_target`), the first refused with "Terrain data (rangefinder)
        not available" without a healthy rangefinder. False (ignored, silently, as ArduSub does) in any other mode
        or case."""
        if self.mode == MODES["ALT_HOLD"] and not type_mask & guided.Z_IGNORE:
            self.holds.depth = -float(alt)
            return True
        if self.mode != MODES["GUIDED"]:
            return False
        position = None
        reference = guided.GLOBAL_FRAMES.get(frame)
        if reference == "terrain" and self.origin is not None:
            if not guided.takes_terrain(type_mask):
                return False
            if self.guided.terrain_range is None and not self.rangefinder.alt_ok(self._t):
                self.texts.append((MAV_SEVERITY_WARNING, guided.TERRAIN_REFUSAL))
                return False
            return self.guided.terrain_target(type_mask, north_east(lat, lon, self.origin), float(alt), velocity,
                                              self.rangefinder.terrain_depth, self._state, t)
        if not type_mask & guided.POS_IGNORE and self.origin is not None and reference in ("sea", "home"):
            north, east = north_east(lat, lon, self.origin)
            position = np.array([north, east, -(alt - self.origin[2] if reference == "sea" else alt)])
        return self.guided.global_target(type_mask, position, velocity, self._state, t)

    def _verify_motor_test(self, t: float) -> None:
        """`Sub::verify_motor_test`: a running test ends, disarming, after MOTOR_TEST_TIMEOUT without a command."""
        if not self.motor_testing or t <= self._test_seen + MOTOR_TEST_TIMEOUT:
            return
        self.texts.append((MAV_SEVERITY_INFO, "Motor test timed out!"))
        self.motor_testing = False
        self.arm(False)
        self._test_timed_out = t

    # -- outputs ---------------------------------------------------------------------------------------------

    def pilot_axes(self) -> np.ndarray:
        """The pilot's (roll, pitch, yaw, throttle, forward, lateral) in [-1, 1] from RC channels 1-6."""
        p = self.params
        return np.array([self.rc.norm_input(ch, p[low], p[trim], p[high])
                         for ch, (low, trim, high) in zip(PILOT_CHANNEL_OF_AXIS, _RC_RANGE)])

    def motor_pwm(self) -> np.ndarray:
        """PWM (n,) of the frame's motors: the test PWMs while a motor test runs (armed or not), else the mixer when
        armed, neutral when disarmed."""
        if self.motor_testing:
            return self._test_pwm
        if not self.armed:
            return self._neutral
        if self._held is not None:
            return self._held
        key = (self.rc.radio_in[:6].tobytes(), self.params.version)
        if key != self._mix_key:                 # the mixer only when the pilot channels or parameters changed
            self._mixed = mixer.to_pwm(self._mix(self.pilot_axes()), *self._pwm_range())
            self._mix_key = key
        return self._mixed

    def _pwm_range(self) -> tuple[float, float]:
        p = self.params
        if 1 <= p["MOT_PWM_MIN"] < p["MOT_PWM_MAX"]:
            return p["MOT_PWM_MIN"], p["MOT_PWM_MAX"]
        return p["RC3_MIN"], p["RC3_MAX"]

    def _mix(self, axes) -> np.ndarray:
        if self._directions_version != self.params.version:      # MOT_n_DIRECTION read again only when changed
            self._directions = [-1.0 if self.params[name] < 0 else 1.0
                                for name in _MOTOR_DIRECTION[:self.frame.motors]]
            self._directions_version = self.params.version
        return mixer.mix(axes, self._directions, self.frame, self.params["MOT_FV_CPLNG_K"])

    def servo_outputs(self) -> np.ndarray:
        """PWM (16,) of SERVO1..16, routed by SERVOn_FUNCTION (0 for unassigned outputs; all 0 with the safety on,
        as measured on ArduSub 4.5.3 SITL)."""
        if self._routing_version != self.params.version:
            functions = np.array([int(self.params[name]) for name in _SERVO_FUNCTION])
            self._motor = (functions >= MOTOR1) & (functions < MOTOR1 + self.frame.motors)
            self._rcin = (functions >= RCIN1) & (functions <= RCIN16)
            self._motor_index = functions[self._motor] - MOTOR1
            self._rcin_index = functions[self._rcin] - RCIN1
            self._routing_version = self.params.version
        out = np.zeros(SERVOS, dtype=np.int32)
        if self.safety_on:
            return out
        out[self._motor] = self.motor_pwm()[self._motor_index]
        out[self._rcin] = self.rc.radio_in[self._rcin_index]
        np.maximum(out, 0, out=out)                 # (np.clip's per-call overhead is larger than the work here)
        return np.minimum(out, UINT16_MAX, out=out)

    # -- status ----------------------------------------------------------------------------------------------

    def base_mode(self) -> int:
        """HEARTBEAT base_mode: custom|stabilize|manual-input (81), +8 guided-type modes, +128 armed."""
        mode = 1 | 16 | 64
        if self.mode in GUIDED_FLAG_MODES:
            mode |= 8
        if self.armed:
            mode |= 128
        return mode

    def system_status(self) -> int:
        """HEARTBEAT system_status: CRITICAL in any failsafe, else ACTIVE armed, BOOT initialising, STANDBY."""
        if self.failsafes.triggered(self.params.firmware):
            return MAV_STATE_CRITICAL
        if self.armed:
            return MAV_STATE_ACTIVE
        return MAV_STATE_STANDBY if self.initialised else MAV_STATE_BOOT
