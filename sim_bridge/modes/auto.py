"""ArduSub's AUTO mode (3) on the built-in vehicle: the stored mission's NAV_WAYPOINT items flown one after the other,
at a depth or (PR #26450, merged in March 2024) at a height above the bottom from the rangefinder.

Re-implemented from ArduPilot's source (4.7-era copies; the search tools hold no 4.7.2 tag):
- The mission (libraries/AP_Mission/AP_Mission.cpp): `start_or_resume` (MIS_RESTART 0 resumes: the command that was
  running starts again; a mission that completed, or never ran, starts from item 1), `update` (a loaded navigation
  command verified every loop; done, the next one started at once), `advance_current_nav_cmd` (a navigation command
  whose start fails is passed over for the next), `complete` (-> `exit_mission`), `stop` (Sub::exit_mode, leaving
  AUTO); `start_command` says "Mission: N TYPE" (INFO; `Mission_Command::type`) before the vehicle's own start.
- ArduSub/commands_logic.cpp `Sub::start_command`: the altitude frame first, for every command: above home (frame 3)
  with a positive altitude "Alt above home must be negative", above the terrain (10) with a negative one "Alt above
  terrain must be positive", any other "Bad alt frame" (an item stored without a position reads as one: ArduSub
  forks note it for GUIDED_ENABLE and CONDITION_YAW in SITL); a command it has no case for "Ignoring command N" (all
  WARNING, the command passed over). `do_nav_wp`: latitude and longitude 0 -> where the vehicle is; altitude 0 -> its
  altitude now (above the terrain needs the terrain database ArduSub lacks, so a depth), the hold time param1 (whole
  s). `verify_nav_wp`: once AC_WPNav has reached the destination, the hold counts; then "Reached command #N" (INFO)
  and, by `verify_command_callback`, MISSION_ITEM_REACHED N. `exit_mission`: `auto_loiter_start`, or ALT_HOLD
  without a position.
- ArduSub/mode_auto.cpp `ModeAuto::init` (the gates: `sim_bridge.modes.gates`): the navigator at the stopping point,
  then the mission. `auto_wp_start(Location)`: the leg to the waypoint (`sim_bridge.modes.wpnav`); refused for want
  of a terrain offset -> "Terrain data (rangefinder) not available" (WARNING) and `failsafe_terrain_on_event`.
  `auto_wp_run`: disarmed, the navigator starts again from where the vehicle is (`wp_and_spline_init`, which counts
  the destination reached: a disarmed vehicle in AUTO steps through its mission, each waypoint after its hold);
  armed, `update_wpnav` (its result to `failsafe_terrain_set_status`) and the position controller, GUIDED's here
  (`sim_bridge.modes.guided.Guided.track`). The heading: WP_YAW_BEHAVIOR's Sub default, CORRECT_XTRACK, the leg's
  bearing (the target's velocity lies along it, so no cross-track correction), slewed at 60 deg/s.
  `auto_loiter_start` / `auto_loiter_run`: the stopping point held, above the EKF origin, heading held.
- The terrain failsafe (ArduSub/failsafe.cpp, events.cpp; `sim_bridge.autopilot.failsafes`): 1 s of failures
  "Failsafe terrain triggered", then `auto_terrain_recover_start` here: with the rangefinder Good or out of range,
  "Attempting auto failsafe recovery" (WARNING), the mission stopped, the stopping point and depth held;
  `auto_terrain_recover_run`: too close, up at WPNAV_SPEED_UP; too far, up at WPNAV_SPEED_DN (4.7-era code: PR
  #33398 makes it descend, later); Good, the depth held and, once healthy for 1.5 s, "Terrain failsafe recovery
  successful!" (INFO) and the mission resumed (its waypoint started again from here); no data "Terrain failsafe
  recovery failure: No Rangefinder!", 10 s "Terrain failsafe recovery timeout!" (CRITICAL), each with
  `failsafe_terrain_act` (FS_TERRAIN_ENAB).
Left out: every other command. Navigation commands ArduSub flies (LOITER_UNLIM/TIME/TURNS, RTL, LAND, GUIDED_ENABLE,
DELAY) are passed over with "Ignoring command N" here; DO and CONDITION items are passed over silently, DO_JUMP
included. Also the pilot's sticks (yaw and leans) and ROI, resuming by MAV_CMD_DO_SET_MISSION_CURRENT or
MISSION_START, the mission's rewind (DO_SET_RESUME_REPEAT_DIST).
"""

from __future__ import annotations

import math

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from rov_mav.model.dynamics import rotation
from rov_mav.units import north_east
from sim_bridge.modes.gates import MODES
from sim_bridge.modes.terrain import GOOD, OUT_OF_RANGE_HIGH, OUT_OF_RANGE_LOW
from sim_bridge.modes.wpnav import Limits, WaypointNav, stopping_point

INFO, WARNING, CRITICAL = mavlink.MAV_SEVERITY_INFO, mavlink.MAV_SEVERITY_WARNING, mavlink.MAV_SEVERITY_CRITICAL
STOPPED, RUNNING, COMPLETE = "stopped", "running", "complete"      # AP_Mission::mission_state
WP, LOITER, TERRAIN_RECOVER = "wp", "loiter", "terrain_recover"   # Sub's AutoMode
NAV_WAYPOINT = mavlink.MAV_CMD_NAV_WAYPOINT
ABOVE_HOME, ABOVE_TERRAIN = 3, 10           # a stored item's frame (`sim_bridge.gcs.missions`)
RECOVER_HEALTHY_FOR = 1.5                   # s of a healthy rangefinder that ends a recovery
RECOVER_TIMEOUT = 10.0                      # s: FS_TERRAIN_RECOVER_TIMEOUT_MS
# `AP_Mission::is_nav_cmd`: below MAV_CMD_NAV_LAST and these
EXTRA_NAV = {mavlink.MAV_CMD_NAV_SET_YAW_SPEED, 42702, 42703}      # NAV_SCRIPT_TIME, NAV_ATTITUDE_TIME
# `Mission_Command::type` of the navigation commands
TYPES = {16: "WP", 82: "SplineWP", 20: "RTL", 17: "LoitUnlim", 19: "LoitTime", 92: "GuidedEnable", 18: "LoitTurns",
         31: "LoitAltitude", 213: "SetYawSpd", 22: "Takeoff", 21: "Land", 30: "ContinueAndChangeAlt",
         83: "AltitudeWait", 84: "VTOLTakeoff", 85: "VTOLLand", 93: "Delay", 94: "PayloadPlace",
         42702: "NavScriptTime", 42703: "NavAttitudeTime"}
# MISSION_CURRENT's mission_state (`GCS_MAVLINK::mission_state`)
MISSION_STATES = {STOPPED: mavlink.MISSION_STATE_NOT_STARTED, RUNNING: mavlink.MISSION_STATE_ACTIVE,
                  COMPLETE: mavlink.MISSION_STATE_COMPLETE}


def is_nav(command: int) -> bool:
    return command <= mavlink.MAV_CMD_NAV_LAST or command in EXTRA_NAV


class Auto:
    """AUTO's mission and waypoint navigation for one boot, flown by `guided` (the GUIDED controller the vehicle
    has). `enter` and `exit` on a mode change, `run` every main-loop pass in AUTO, armed or not; `reached` holds the
    items reached for MISSION_ITEM_REACHED until the caller takes them. The vehicle `sub` they are given has
    params, texts, armed, origin, rangefinder, failsafes, mission(), position_ok(), set_mode() and arm()."""

    def __init__(self, guided):
        self.guided = guided
        self.nav = WaypointNav()
        self.state = STOPPED
        self.index: int | None = None       # `_nav_cmd.index`: the navigation command loaded (or last tried)
        self.loaded = False                 # `_flags.nav_cmd_loaded`
        self.submode = LOITER
        self.track_heading = False          # the leg's bearing (CORRECT_XTRACK), else the heading held
        self.hold = 0.0                     # s: `loiter_time_max`
        self.held_since: float | None = None   # `loiter_time`
        self.reached: list[int] = []
        self._recover_start = -math.inf
        self._healthy_since: float | None = None   # `rangefinder_recovery_ms` (a static in ArduSub)
        self._hold = np.zeros(3)            # NED m: the recovery's position and depth target
        self._sub = None
        self._state = (np.zeros(6), np.zeros(6))
        self._t = 0.0

    # -- mode changes ------------------------------------------------------------------------------------------

    def enter(self, sub, state, t: float) -> None:
        """`ModeAuto::init` once the gates passed: the navigator at the stopping point, the mission started or
        resumed (MIS_RESTART)."""
        self._bind(sub, state, t)
        self.submode = LOITER
        self.track_heading = False
        self.nav.init(self._stop(), t)
        if int(sub.params["MIS_RESTART"]) == 1:
            self._start()
        else:
            self._resume()

    def exit(self) -> None:
        """`Sub::exit_mode` leaving AUTO: a running mission stops."""
        if self.state == RUNNING:
            self.state = STOPPED

    def mission_current(self, count: int) -> tuple[int, int]:
        """MISSION_CURRENT's (seq, mission_state) with `count` items stored, home's included
        (`get_current_nav_index`: 0 before any)."""
        state = MISSION_STATES[self.state] if count > 1 else mavlink.MISSION_STATE_NO_MISSION
        return self.index or 0, state

    # -- the loop ----------------------------------------------------------------------------------------------

    def run(self, sub, state, t: float, dt: float) -> list[float] | None:
        """`ModeAuto::run`: the mission's update, then the submode's controller; the mixer's axes, or None when
        nothing is flown (disarmed, or the mode left)."""
        self._bind(sub, state, t)
        self._update()
        if sub.mode != MODES["AUTO"]:
            return None
        if self.submode == TERRAIN_RECOVER:
            return self._recover_run(dt)
        return self._nav_run(dt)

    def _bind(self, sub, state, t: float) -> None:
        self._sub, self._t = sub, t
        if state is not None:
            self._state = (np.asarray(state[0], dtype=float), np.asarray(state[1], dtype=float))

    def _v_ned(self) -> np.ndarray:
        eta, nu = self._state
        return rotation(eta) @ nu[:3]

    def _stop(self) -> np.ndarray:
        return stopping_point(self._state[0], self._v_ned(), self._sub.params.guided_gains())

    def _terrain_depth(self) -> float | None:
        """The bottom's depth while AC_WPNav has a terrain offset: the rangefinder enabled and healthy."""
        rf = self._sub.rangefinder
        return rf.terrain_depth if rf.enabled and rf.healthy else None

    def _nav_run(self, dt: float) -> list[float] | None:
        """`auto_wp_run` / `auto_loiter_run`."""
        sub, t, (eta, nu) = self._sub, self._t, self._state
        if not sub.armed:
            self.nav.init(self._stop(), t)
            return None
        gains = sub.params.guided_gains()
        terrain = self._terrain_depth()
        v = self._v_ned()
        out = self.nav.advance(np.array([eta[0], eta[1], -eta[2]]), np.array([v[0], v[1], -v[2]]), terrain,
                               Limits.from_gains(gains), t, dt)
        sub.failsafes.terrain_status(out is not None, t)
        guided = self.guided
        if out is None:                    # the target stays where it was
            guided.track(guided.position, np.zeros(3), t, guided.terrain_range)
        else:
            target, velocity = out
            ned_velocity = (velocity[0], velocity[1], -velocity[2])
            if self.nav.terrain:
                guided.track((target[0], target[1], terrain - target[2]), ned_velocity, t, float(target[2]))
            else:
                guided.track((target[0], target[1], -target[2]), ned_velocity, t)
        self._heading(self.nav.bearing() if self.submode == WP and self.track_heading else None)
        return guided.axes(gains, eta, nu, t, dt, terrain_depth=terrain if self.nav.terrain else None)

    def _heading(self, heading: float | None) -> None:
        """The heading flown: `heading`, or the one held (AUTO_YAW_HOLD: the attitude target's)."""
        guided = self.guided
        if heading is None:
            heading = guided.heading_target if guided.heading_target is not None else float(self._state[0][5])
        guided.heading = float(heading)

    # -- the mission (AP_Mission) ------------------------------------------------------------------------------

    def _items(self) -> list:
        return self._sub.mission()

    def _start(self) -> None:
        self.state = RUNNING
        self.index, self.loaded = None, False
        if not self._advance():
            self._complete()

    def _resume(self) -> None:
        if self.state == COMPLETE:
            return self._start()
        if self.state == STOPPED:
            self.state = RUNNING
        if self.index is None or self.index >= len(self._items()):   # never ran, or its command is gone
            return self._start()
        if self.loaded:                             # `set_current_cmd`: the running command starts again
            self.loaded = False
            if not self._advance(self.index):
                self._complete()

    def _update(self) -> None:
        """`AP_Mission::update`."""
        if self.state != RUNNING or not self._items():
            return
        if not self.loaded or self.index is None:
            if not self._advance():
                self._complete()
            return
        if self._verify(self.index):
            self.reached.append(self.index)
            self.loaded = False
            if not self._advance():
                self._complete()

    def _advance(self, start: int | None = None) -> bool:
        """`advance_current_nav_cmd` from `start` (or past the current one): the next navigation command that
        starts; False past the end."""
        if self.state != RUNNING:
            return False
        items = self._items()
        i = start if start is not None else 1 if self.index is None else self.index + 1
        while not self.loaded:
            if i >= len(items):
                return False
            if is_nav(items[i].command):
                self.index = i
                self.loaded = self._start_command(i, items[i])
            i += 1
        return True

    def _complete(self) -> None:
        """`AP_Mission::complete` and `Sub::exit_mission`."""
        self.state = COMPLETE
        if not self._sub.position_ok():
            self._sub.set_mode(MODES["ALT_HOLD"])
            return
        self.submode, self.track_heading = LOITER, False          # `auto_loiter_start`
        stop = self._stop()
        self.nav.set_destination(stop, False, self._terrain_depth(), stop, self._t)

    # -- the commands (commands_logic.cpp) ---------------------------------------------------------------------

    def _start_command(self, index: int, item) -> bool:
        texts = self._sub.texts
        texts.append((INFO, f"Mission: {index} {TYPES.get(item.command, '?')}"))
        altitude_cm = round(item.z * 100)
        if item.frame == ABOVE_HOME and altitude_cm > 0:
            texts.append((WARNING, "Alt above home must be negative"))
            return False
        if item.frame == ABOVE_TERRAIN and altitude_cm < 0:
            texts.append((WARNING, "Alt above terrain must be positive"))
            return False
        if item.frame not in (ABOVE_HOME, ABOVE_TERRAIN):
            texts.append((WARNING, "Bad alt frame"))
            return False
        if item.command != NAV_WAYPOINT:
            texts.append((WARNING, f"Ignoring command {item.command}"))
            return False
        self._do_nav_wp(item, altitude_cm)
        return True

    def _do_nav_wp(self, item, altitude_cm: int) -> None:
        eta = self._state[0]
        if item.x == 0 and item.y == 0:
            north, east = float(eta[0]), float(eta[1])
        else:
            north, east = north_east(item.x * 1e-7, item.y * 1e-7, self._sub.origin or (0.0, 0.0, 0.0))
        if altitude_cm == 0:                        # where it is now, as a depth
            destination, terrain = (north, east, -float(eta[2])), False
        else:                                       # above home (the origin, at the surface) or above the bottom
            destination, terrain = (north, east, float(item.z)), item.frame == ABOVE_TERRAIN
        self.hold, self.held_since = float(item.params[0]), None
        self._wp_start(destination, terrain)

    def _wp_start(self, destination, terrain: bool) -> None:
        """`ModeAuto::auto_wp_start(const Location&)`."""
        self.submode = WP
        if not self.nav.set_destination(destination, terrain, self._terrain_depth(), self._stop(), self._t):
            self._sub.texts.append((WARNING, "Terrain data (rangefinder) not available"))
            self._sub.failsafes.terrain_event(self._sub, self._t)
            return
        self.track_heading = True

    def _verify(self, index: int) -> bool:
        """`verify_nav_wp`: the destination reached, then the hold."""
        if not self.nav.reached:
            return False
        if self.held_since is None:
            self.held_since = self._t
        if self._t - self.held_since + 1e-9 >= self.hold:
            self._sub.texts.append((INFO, f"Reached command #{index}"))
            return True
        return False

    # -- the terrain failsafe's recovery -----------------------------------------------------------------------

    def recover_start(self, sub, t: float) -> bool:
        """`auto_terrain_recover_start`: False when the rangefinder has no data (the failsafe acts instead)."""
        if sub.rangefinder.status not in (GOOD, OUT_OF_RANGE_LOW, OUT_OF_RANGE_HIGH):
            return False
        self._bind(sub, None, t)
        self.submode = TERRAIN_RECOVER
        self._recover_start = t
        self.state = STOPPED if self.state == RUNNING else self.state
        stop, eta = self._stop(), self._state[0]
        self._hold = np.array([stop[0], stop[1], eta[2]])
        sub.texts.append((WARNING, "Attempting auto failsafe recovery"))
        return True

    def _recover_run(self, dt: float) -> list[float] | None:
        """`auto_terrain_recover_run` (4.7-era: going on after the failsafe acted within the pass)."""
        sub, t, (eta, nu) = self._sub, self._t, self._state
        if not sub.armed:
            self._hold = np.array([eta[0], eta[1], eta[2]])
            return None
        gains, rf = sub.params.guided_gains(), sub.rangefinder
        climb = 0.0                                     # m/s up
        if rf.status == OUT_OF_RANGE_LOW:
            climb, self._healthy_since = gains["WPNAV_SPEED_UP"] * 0.01, None
        elif rf.status == OUT_OF_RANGE_HIGH:
            climb, self._healthy_since = abs(gains["WPNAV_SPEED_DN"]) * 0.01, None
        elif rf.status == GOOD:
            if rf.healthy:
                if self._healthy_since is None:
                    self._healthy_since = t
                    self._hold[2] = eta[2]              # the depth controller relaxed: the depth now
                if t > self._healthy_since + RECOVER_HEALTHY_FOR:
                    sub.texts.append((INFO, "Terrain failsafe recovery successful!"))
                    sub.failsafes.terrain_status(True, t)
                    sub.failsafes.terrain = False
                    self.submode, self._healthy_since = LOITER, None
                    self._resume()
        else:
            sub.texts.append((CRITICAL, "Terrain failsafe recovery failure: No Rangefinder!"))
            self._healthy_since = None
            sub.failsafes.terrain_act(sub)
            return None
        if t > self._recover_start + RECOVER_TIMEOUT:
            sub.texts.append((CRITICAL, "Terrain failsafe recovery timeout!"))
            sub.failsafes.terrain_act(sub)
        if not sub.armed or sub.mode != MODES["AUTO"]:
            return None
        self._hold[2] -= climb * dt
        self.guided.track(self._hold.copy(), (0.0, 0.0, -climb), t)
        self._heading(None)
        return self.guided.axes(gains, eta, nu, t, dt)
