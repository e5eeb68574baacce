"""A dive as its telemetry log tells it: the vehicle's state decoded as the runner decodes the live link
(`StateDecoder`), its outputs, battery, arming and modes, texts, parameters, the commands stations sent it, and the
mission it held (MISSION_ITEM_INT traffic either way); and, position or not, what its own sensors said: attitude
and heading (ATTITUDE), the Bar30's pressure (SCALED_PRESSURE2), the rangefinder (DISTANCE_SENSOR facing down; the
autopilot's RANGEFINDER only in a log without one: it is a copy of the same sounder without its status, out-of-range
readings included) - most BlueROV2s have no position source, and their logs no LOCAL_POSITION_NED.

`DiveRecorder.take(wall, msg)` for every message in log order, then `finish()`. The vehicle is the first system
that sends a vehicle's HEARTBEAT (or state telemetry); what arrives before it is known is held and replayed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from rov_mav.flight.record.history import History
from rov_mav.flight.session.link import CHANNELS, MOTOR_TEST_PWM, NEUTRAL, mavlink
from rov_mav.flight.session.truth import Truth
from rov_mav.flight.state.vehicle_state import STATE_MESSAGES, StateDecoder
from rov_mav.mission.mission_items import MissionItem
from rov_mav.review import controller_tracking

HELD = 20000                 # messages held while the vehicle is not yet known
UNSET = (0, 65535)           # RC_CHANNELS_OVERRIDE values that leave a channel alone
INVALID_SIGNAL = 1           # DISTANCE_SENSOR.signal_quality: 0 unknown, 1 invalid, up to 100 perfect


@dataclass
class Dive:
    """The decoded log. Times are wall seconds (the log's clock) unless named `t` (vehicle s since boot)."""

    vehicle: tuple[int, int] | None               # (sysid, compid)
    vehicle_type: int | None                      # MAV_TYPE of its HEARTBEAT
    state_t: np.ndarray                           # (N,) vehicle s of each complete state
    state_wall: np.ndarray                        # (N,) log time its completing message was recorded
    eta: np.ndarray                               # (N, 6)
    nu: np.ndarray                                # (N, 6)
    clock_wall: np.ndarray                        # (K,) log times of the vehicle's timestamped messages ...
    clock_t: np.ndarray                           # (K,) ... and their time_boot_ms, s
    servo_t: np.ndarray                           # (M,) SERVO_OUTPUT_RAW time_usec, s
    servo: np.ndarray                             # (M, 8) us
    overrides: dict[int, tuple[np.ndarray, np.ndarray]]   # sysid -> (wall (K,), channels 1-8 (K, 8), NaN = unset)
    joysticks: dict[int, np.ndarray]              # sysid -> wall (K,) of its MANUAL_CONTROL
    motor_tests: dict[int, tuple[np.ndarray, np.ndarray]]   # sysid -> (wall (K,), outputs 1-8 (K, 8)): its
                                                  # MAV_CMD_DO_MOTOR_TEST PWMs, a row at each command of output 8
    power_wall: np.ndarray                        # (P,) SYS_STATUS
    voltage: np.ndarray                           # (P,) V (NaN when not reported)
    current: np.ndarray                           # (P,) A (NaN when not reported)
    consumed_wall: np.ndarray                     # (Q,) BATTERY_STATUS
    consumed_mah: np.ndarray                      # (Q,) mAh since the vehicle booted (NaN when not reported)
    heartbeat_wall: np.ndarray                    # (H,) the vehicle's HEARTBEATs
    armed: np.ndarray                             # (H,) bool
    mode: np.ndarray                              # (H,) custom_mode
    texts: list[tuple[float, int, int, str]]      # (wall, sysid, severity, text), every station's
    params: dict[str, float]                      # the vehicle's PARAM_VALUEs, last value of each
    param_changes: list[tuple[float, str, float]]  # (wall, name, value) of the sets the vehicle confirmed
    mission: dict[int, MissionItem]               # seq -> item of the last mission seen whole (else the longest
                                                  #   partial one); item 0 is home
    mission_complete: bool
    mission_progress: list[tuple[float, str]]     # (wall, text): current item changes, items reached
    home: object | None                           # the vehicle's last HOME_POSITION
    origin: object | None                         # ... and GPS_GLOBAL_ORIGIN
    others: set[int] = field(default_factory=set)      # other systems (sysids) on the link
    truth_wall: np.ndarray = field(default_factory=lambda: np.zeros(0))     # (T,) SIM_STATE's log times ...
    truth: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))     # (T, 3) ... the true NED position
    attitude_wall: np.ndarray = field(default_factory=lambda: np.zeros(0))  # (A,) ATTITUDE's log times ...
    attitude: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))  # (A, 3) ... roll, pitch, yaw (rad)
    pressure_wall: np.ndarray = field(default_factory=lambda: np.zeros(0))  # (B,) SCALED_PRESSURE2's log times ...
    pressure_abs: np.ndarray = field(default_factory=lambda: np.zeros(0))   # (B,) ... press_abs (hPa)
    altitude_wall: np.ndarray = field(default_factory=lambda: np.zeros(0))  # (U,) GLOBAL_POSITION_INT's log times ...
    altitude: np.ndarray = field(default_factory=lambda: np.zeros(0))       # (U,) ... relative_alt: ArduSub's own
                                                                            # altitude (m, up; negative underwater)
    range_wall: np.ndarray = field(default_factory=lambda: np.zeros(0))     # (R,) the rangefinder's log times ...
    range_m: np.ndarray = field(default_factory=lambda: np.zeros(0))        # (R,) ... its distance (m)
    targets: dict = field(default_factory=dict)   # name -> controller_tracking.Errors: ArduSub's own controllers
                                                  # against the targets they logged (NAV_CONTROLLER_OUTPUT in a .tlog)
    onboard: dict = field(default_factory=dict)   # what only a DataFlash log holds, summed up (`review.onboard`)


class DiveRecorder:
    def __init__(self):
        self.decoder = StateDecoder()
        self.truth = Truth()                      # a simulator's SIM_STATE, when the log has one
        self._truth = History(wall=1, position=3)
        self._attitude = History(wall=1, rpy=3)
        self._pressure = History(wall=1, abs=1)
        self._altitude = History(wall=1, m=1)
        self._range = History(wall=1, m=1)
        self._range_copy = History(wall=1, m=1)   # RANGEFINDER: used only without a DISTANCE_SENSOR
        self._nav = History(wall=1, targets=4)
        self.vehicle: tuple[int, int] | None = None
        self.vehicle_type: int | None = None
        self._held: list[tuple[float, object]] = []
        self._states = History(t=1, wall=1, eta=6, nu=6)
        self._clock = History(wall=1, t=1)
        self._servo = History(t=1, pwm=CHANNELS)
        self._power = History(wall=1, voltage=1, current=1)
        self._consumed = History(wall=1, mah=1)
        self._heartbeats = History(wall=1, armed=1, mode=1)
        self._overrides: dict[int, History] = {}
        self._joysticks: dict[int, History] = {}
        self._motor_tests: dict[int, History] = {}
        self._test_pwm: dict[int, np.ndarray] = {}    # sysid -> its motor-test PWMs so far
        self.texts: list[tuple[float, int, int, str]] = []
        self.params: dict[str, float] = {}
        self.param_changes: list[tuple[float, str, float]] = []
        self._mission_count: int | None = None
        self._items: dict[int, MissionItem] = {}
        self._mission: dict[int, MissionItem] = {}
        self._mission_complete = False
        self._current_item: int | None = None
        self.mission_progress: list[tuple[float, str]] = []
        self.home = self.origin = None
        self.others: set[int] = set()

    def take(self, wall: float, msg) -> None:
        if self.vehicle is None and not self._identify(msg):
            if len(self._held) < HELD:
                self._held.append((wall, msg))
            return
        if self._held:
            held, self._held = self._held, []
            for w, m in held:
                self._route(w, m)
        self._route(wall, msg)

    def finish(self) -> Dive:
        """The dive so far (messages still held, from no vehicle that identified itself, are left out)."""
        self._close_mission()
        order = np.argsort(self._clock.column("wall"), kind="stable")
        ranges = self._range if self._range.size else self._range_copy
        return Dive(
            vehicle=self.vehicle, vehicle_type=self.vehicle_type,
            state_t=self._states.column("t"), state_wall=self._states.column("wall"),
            eta=self._states.column("eta"), nu=self._states.column("nu"),
            clock_wall=self._clock.column("wall")[order], clock_t=self._clock.column("t")[order],
            servo_t=self._servo.column("t"), servo=self._servo.column("pwm"),
            overrides={s: (h.column("wall"), h.column("pwm")) for s, h in self._overrides.items()},
            joysticks={s: h.column("wall") for s, h in self._joysticks.items()},
            motor_tests={s: (h.column("wall"), h.column("pwm")) for s, h in self._motor_tests.items()},
            power_wall=self._power.column("wall"), voltage=self._power.column("voltage"),
            current=self._power.column("current"),
            consumed_wall=self._consumed.column("wall"), consumed_mah=self._consumed.column("mah"),
            heartbeat_wall=self._heartbeats.column("wall"), armed=self._heartbeats.column("armed").astype(bool),
            mode=self._heartbeats.column("mode").astype(int),
            texts=self.texts, params=self.params, param_changes=self.param_changes,
            mission=self._mission, mission_complete=self._mission_complete, mission_progress=self.mission_progress,
            home=self.home, origin=self.origin, others=self.others,
            truth_wall=self._truth.column("wall"), truth=self._truth.column("position"),
            attitude_wall=self._attitude.column("wall"), attitude=self._attitude.column("rpy"),
            pressure_wall=self._pressure.column("wall"), pressure_abs=self._pressure.column("abs"),
            altitude_wall=self._altitude.column("wall"), altitude=self._altitude.column("m"),
            range_wall=ranges.column("wall"), range_m=ranges.column("m"),
            targets=controller_tracking.telemetry_errors(self._nav.column("wall"), self._nav.column("targets"),
                                                         self._attitude.column("wall"), self._attitude.column("rpy")))

    # -- who is the vehicle ----------------------------------------------------------------------------------

    def _identify(self, msg) -> bool:
        kind = msg.get_type()
        vehicle_heartbeat = kind == "HEARTBEAT" and msg.type != mavlink.MAV_TYPE_GCS and \
            msg.autopilot != mavlink.MAV_AUTOPILOT_INVALID
        if not (vehicle_heartbeat or kind in STATE_MESSAGES):
            return False
        self.vehicle = (msg.get_srcSystem(), msg.get_srcComponent())
        return True

    def _route(self, wall: float, msg) -> None:
        if (msg.get_srcSystem(), msg.get_srcComponent()) == self.vehicle:
            self._from_vehicle(wall, msg)
        elif msg.get_srcSystem() == self.vehicle[0] and msg.get_type() == "DISTANCE_SENSOR":
            self._rangefinder(wall, msg)                # an echo sounder of the companion's (BlueOS's Ping service)
        else:
            self._from_station(wall, msg)

    def _rangefinder(self, wall: float, msg) -> None:
        """DISTANCE_SENSOR facing down, within its range and not flagged invalid: the distance above the bottom."""
        if msg.orientation == mavlink.MAV_SENSOR_ROTATION_PITCH_270 \
                and msg.min_distance <= msg.current_distance <= msg.max_distance \
                and getattr(msg, "signal_quality", 0) != INVALID_SIGNAL:
            self._range.append(wall=wall, m=msg.current_distance / 100.0)

    # -- the vehicle's messages ------------------------------------------------------------------------------

    def _from_vehicle(self, wall: float, msg) -> None:
        kind = msg.get_type()
        boot_ms = getattr(msg, "time_boot_ms", None)
        if boot_ms is not None:
            self._clock.append(wall=wall, t=boot_ms / 1000.0)
        if self.truth.update(msg, wall):
            self._truth.append(wall=wall, position=self.truth.position)
        if self.decoder.update(msg):
            state = self.decoder.state(wall)
            self._states.append(t=state.t, wall=wall, eta=state.eta, nu=state.nu)
        if kind == "HEARTBEAT":
            self.vehicle_type = msg.type
            self._heartbeats.append(wall=wall, armed=bool(msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED),
                                    mode=msg.custom_mode)
        elif kind == "ATTITUDE":
            self._attitude.append(wall=wall, rpy=[msg.roll, msg.pitch, msg.yaw])
        elif kind == "SCALED_PRESSURE2":                    # the Bar30, ArduSub's second barometer
            self._pressure.append(wall=wall, abs=msg.press_abs)
        elif kind == "GLOBAL_POSITION_INT":                 # Sub's alt/relative_alt: its depth estimate, negated
            self._altitude.append(wall=wall, m=msg.relative_alt / 1000.0)
        elif kind == "DISTANCE_SENSOR":
            self._rangefinder(wall, msg)
        elif kind == "RANGEFINDER":
            self._range_copy.append(wall=wall, m=msg.distance)
        elif kind == "NAV_CONTROLLER_OUTPUT":              # ArduSub's attitude targets and altitude error
            self._nav.append(wall=wall, targets=[msg.nav_roll, msg.nav_pitch, msg.nav_bearing, msg.alt_error])
        elif kind == "SERVO_OUTPUT_RAW":
            self._servo.append(t=msg.time_usec / 1e6,
                               pwm=[getattr(msg, f"servo{i}_raw") for i in range(1, CHANNELS + 1)])
        elif kind == "SYS_STATUS":
            voltage = np.nan if msg.voltage_battery in UNSET else msg.voltage_battery / 1000.0
            current = np.nan if msg.current_battery < 0 else msg.current_battery / 100.0
            self._power.append(wall=wall, voltage=voltage, current=current)
        elif kind == "BATTERY_STATUS" and msg.id == 0:
            self._consumed.append(wall=wall, mah=np.nan if msg.current_consumed < 0 else float(msg.current_consumed))
        elif kind == "PARAM_VALUE":
            name = msg.param_id
            if msg.param_index == 65535 or (name in self.params and self.params[name] != msg.param_value):
                self.param_changes.append((wall, name, float(msg.param_value)))
            self.params[name] = float(msg.param_value)
        elif kind == "STATUSTEXT":
            self.texts.append((wall, msg.get_srcSystem(), msg.severity, msg.text))
        elif kind == "HOME_POSITION":
            self.home = msg
        elif kind == "GPS_GLOBAL_ORIGIN":
            self.origin = msg
        elif kind == "MISSION_CURRENT" and msg.seq != self._current_item:
            self._current_item = msg.seq
            self.mission_progress.append((wall, f"mission: current item {msg.seq}"))
        elif kind == "MISSION_ITEM_REACHED":
            self.mission_progress.append((wall, f"mission: item {msg.seq} reached"))
        self._mission_traffic(msg, kind)

    # -- other stations' messages ----------------------------------------------------------------------------

    def _from_station(self, wall: float, msg) -> None:
        kind, sysid = msg.get_type(), msg.get_srcSystem()
        if sysid != self.vehicle[0]:
            self.others.add(sysid)
        if kind == "RC_CHANNELS_OVERRIDE" and msg.target_system == self.vehicle[0]:
            values = [getattr(msg, f"chan{i}_raw") for i in range(1, CHANNELS + 1)]
            if all(v in UNSET for v in values):
                return
            history = self._overrides.setdefault(sysid, History(wall=1, pwm=CHANNELS))
            history.append(wall=wall, pwm=[np.nan if v in UNSET else v for v in values])
        elif kind == "MANUAL_CONTROL" and msg.target == self.vehicle[0]:
            self._joysticks.setdefault(sysid, History(wall=1)).append(wall=wall)
        elif kind in ("COMMAND_LONG", "COMMAND_INT") and msg.command == mavlink.MAV_CMD_DO_MOTOR_TEST \
                and msg.target_system == self.vehicle[0]:
            self._motor_test(wall, sysid, msg)
        elif kind == "STATUSTEXT":
            self.texts.append((wall, sysid, msg.severity, msg.text))
        else:
            self._mission_traffic(msg, kind)

    def _motor_test(self, wall: float, sysid: int, msg) -> None:
        """A DO_MOTOR_TEST with a PWM for output param1 (0-based, as ArduSub's board order): the station's eight
        PWMs are a row once its command for the last output arrives (a rov-mav run sends outputs 1..8 in a row)."""
        output = int(msg.param1) if math.isfinite(msg.param1) else -1
        if msg.param2 != MOTOR_TEST_PWM or not 0 <= output < CHANNELS:
            return
        pwm = self._test_pwm.setdefault(sysid, np.full(CHANNELS, float(NEUTRAL)))
        pwm[output] = msg.param3
        if output == CHANNELS - 1:
            self._motor_tests.setdefault(sysid, History(wall=1, pwm=CHANNELS)).append(wall=wall, pwm=pwm.copy())

    # -- the mission, either way -----------------------------------------------------------------------------

    def _mission_traffic(self, msg, kind: str) -> None:
        if getattr(msg, "mission_type", 0) != mavlink.MAV_MISSION_TYPE_MISSION:
            return
        if kind == "MISSION_COUNT":
            self._close_mission()
            self._mission_count, self._items = msg.count, {}
        elif kind == "MISSION_CLEAR_ALL":
            self._close_mission()
            self._mission_count, self._items = 0, {}
            self._mission, self._mission_complete = {}, True
        elif kind in ("MISSION_ITEM_INT", "MISSION_ITEM"):
            scale = 1e-7 if kind == "MISSION_ITEM_INT" and _global(msg.frame) else 1.0
            self._items[msg.seq] = MissionItem(f"vehicle item {msg.seq}", msg.command, msg.frame,
                                               (msg.param1, msg.param2, msg.param3, msg.param4, msg.x * scale,
                                                msg.y * scale, msg.z))
            if self._mission_count is not None and len(self._items) == self._mission_count:
                self._close_mission()

    def _close_mission(self) -> None:
        """Keep what was transferred: a whole mission always, a partial one only while nothing better is known."""
        if not self._items:
            return
        whole = self._mission_count is not None and len(self._items) == self._mission_count
        if whole or (not self._mission_complete and len(self._items) > len(self._mission)):
            self._mission, self._mission_complete = dict(sorted(self._items.items())), whole
        if whole:
            self._mission_count, self._items = None, {}


def _global(frame: int) -> bool:
    """Frames whose x, y are latitude and longitude (MISSION_ITEM_INT carries them in degrees * 1e7)."""
    return frame not in (mavlink.MAV_FRAME_LOCAL_NED, mavlink.MAV_FRAME_LOCAL_ENU, mavlink.MAV_FRAME_MISSION,
                         mavlink.MAV_FRAME_BODY_NED, mavlink.MAV_FRAME_BODY_FRD, mavlink.MAV_FRAME_LOCAL_OFFSET_NED,
                         mavlink.MAV_FRAME_BODY_OFFSET_NED)
