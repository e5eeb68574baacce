"""The MAVLink session with an ArduSub vehicle: connect, identify, parameters, mode, arming, streams, overrides,
motor tests.

Rates are counted in vehicle time (`VehicleClock`): the GCS heartbeat (1 Hz) and the held RC override and motor test
(the control rate) go out as often as the vehicle's own clock asks, so a vehicle running N x faster than real time
never sees a lost link. Everything that waits for an answer pumps the link meanwhile (so heartbeats and overrides
keep flowing). A request (parameter read or set, command) is sent again while unanswered, each wait longer than the
last (RETRY_GROWTH, up to RETRY_LONGEST wall s), and given up after RETRY_BUDGET wall s, or sooner once the vehicle
has sent nothing for SILENCE wall s: a 30 % loss each way (half the round trips fail) is ridden through, a vehicle
that is gone is not waited for. The first wait is RTT_MARGIN smoothed round trips (timed on requests answered at the
first send, as TCP times its segments: RFC 6298), within RETRY_MIN..RETRY_FIRST.
"""

from __future__ import annotations

import math

import os
import secrets
import socket
import time
import itertools
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil  # noqa: E402

from rov_mav.flight.session.vehicle_clock import RoundTrip  # noqa: E402
from rov_mav.flight.session.stations import OverrideEcho, StationWatch  # noqa: E402
from rov_mav.flight.session.vehicle_clock import VehicleClock  # noqa: E402
from rov_mav.signing import UNSIGNED_RADIO, VEHICLE_HEARTBEATS, Rejections, advance, check_signature_first  # noqa: E402
from rov_mav.units import lat_lon  # noqa: E402

mavutil.set_dialect("ardupilotmega")
mavlink = mavutil.mavlink

HEARTBEAT_PERIOD = 1.0          # vehicle s
MANUAL = 19                     # ArduSub custom_mode
GUIDED = 4
POS_VEL_YAW = 0x9C0              # SET_POSITION_TARGET type_mask: acceleration and yaw rate ignored
POS_VEL = 0xDC0                  # ... acceleration, yaw and yaw rate ignored
POS_VEL_ACC_YAW = 0x800          # ... only the yaw rate ignored (ArduSub 4.7.2's Guided_PosVelAccel)
ACCEL_TARGETS_FROM = (4, 7, 2)   # the first ArduSub that takes them (PR #34298); before, such a target is dropped
NEUTRAL = 1500
CHANNELS = 8
RC_FIELDS = 18
RELEASE = 0                     # RC_CHANNELS_OVERRIDE, channels 1-8: hand the channel back
MOTOR_TEST_PWM = 1              # MAV_CMD_DO_MOTOR_TEST param2: MOTOR_TEST_THROTTLE_PWM
MOTOR_TEST_BOARD = 2            # ... param6: MOTOR_TEST_ORDER_BOARD, param1 the 0-based output (ArduSub 4.5)
TEXTS_KEPT = 20                 # the vehicle's STATUSTEXTs kept (an arming refusal's reasons, a failsafe's words)
MOTOR_TEST_TIMEOUT = 0.5        # vehicle s after the last DO_MOTOR_TEST until ArduSub ends the test and disarms
RETRY_FIRST = 0.3               # wall s before the first resend while no round trip was timed (> 2 x 100 ms)
RETRY_MIN = 0.05                # wall s: the shortest wait before a resend
RTT_MARGIN = 3.0                # round trips to wait before the first resend
RTT_GAIN = 0.125                # weight of a new round-trip sample in the smoothed one (RFC 6298)
RETRY_GROWTH = 1.5              # each further wait is this much longer ...
RETRY_LONGEST = 0.5             # ... up to this many wall s
RETRY_BUDGET = 10.0             # wall s before an unanswered request is given up
SILENCE = 3.0                   # wall s without a message from the vehicle: it is gone, stop resending
HEARTBEAT_CONFIRM = 2.5         # heartbeat periods to wait for one showing a command's effect, before resending it
MAX_CONFIRMATION = 255          # COMMAND_LONG.confirmation: 0 the first time, then +1 per resend
RECEIVE_BUFFER = 1 << 20         # bytes
GCS_SYSID_PARAMS = ("MAV_GCS_SYSID", "SYSID_MYGCS")   # ArduSub 4.7+, before 4.7
TIMESYNC_PERIOD = 0.25          # vehicle s between TIMESYNC requests while flying (the round trip the prediction uses)
TIMESYNC_KEEP = 32              # requests remembered, to recognise the vehicle's answers to ours
UNSIGNED_GRACE = 2.0            # wall s of rejected vehicle HEARTBEATs (4 signed hellos sent) before refusing


class LinkError(Exception):
    """The session cannot go on; the message says why in one line."""


@dataclass(frozen=True)
class VehicleId:
    """Who answered: from its HEARTBEAT."""

    sysid: int
    compid: int
    mav_type: int
    autopilot: int


# ArduSub's mode numbers (ArduSub/mode.h, `Mode::Number`): pymavlink's table and the two it lacks
MODE_NAMES = {**mavutil.mode_mapping_sub, 20: "MOTOR_DETECT", 21: "SURFTRAK"}


def mode_name(custom_mode: int) -> str:
    """ArduSub's name of a custom_mode (MANUAL, POSHOLD, SURFTRAK, ...), or the number."""
    return MODE_NAMES.get(custom_mode, str(custom_mode))


def _enum_name(enum: str, value: int) -> str:
    entry = mavlink.enums.get(enum, {}).get(value)
    return entry.name if entry is not None else str(value)


class Session:
    """One link to one vehicle. Create with `Session.open(target)`, then `connect()`."""

    def __init__(self, conn, clock: VehicleClock, describe: str):
        self.conn = conn
        self.clock = clock
        self.target = describe
        self.vehicle: VehicleId | None = None
        self.heartbeat = None                 # the vehicle's last HEARTBEAT
        self.origins: dict[str, object] = {}  # its last GPS_GLOBAL_ORIGIN and HOME_POSITION, whoever read them
        self.override: list[int] | None = None   # PWMs held (resent at `override_rate` vehicle Hz)
        self.override_rate = 50.0
        self.motor_test: list[int] | None = None   # motor-test PWMs held (resent at `override_rate` vehicle Hz)
        self.motor_test_answers = {"accepted": 0, "refused": 0}   # COMMAND_ACKs of DO_MOTOR_TEST from the vehicle
        self.motor_test_stopped: str | None = None   # why the held test was dropped for good (a refusal, a disarm)
        self.interrupt: Callable[[], None] | None = None   # called while waiting; may raise to stop waiting
        self.stations: StationWatch | None = None   # other stations on the link, once the vehicle is known
        self.echo = OverrideEcho()            # the overrides sent recently, to recognise them in RC_CHANNELS
        self.taps: list[Callable[[object, bool], None]] = []   # (msg, outgoing) for every message in and out
        self.texts: deque[tuple[float, str]] = deque(maxlen=TEXTS_KEPT)   # the vehicle's latest STATUSTEXTs,
                                                                          # with the vehicle time they came at
        self.texts_seen = 0                                   # how many STATUSTEXTs the vehicle has sent us
        self.heartbeats = False
        self.rejections: Rejections | None = None   # with a signing key: what the signature check refused
        self._unsigned_since: float | None = None   # wall s of the first rejected vehicle HEARTBEAT
        self._next_heartbeat = 0.0
        self._last_override_t = -1e9
        self._last_motor_test_t = -1e9
        self._wall_last_heartbeat = -1e9
        self._heard = time.monotonic()         # wall s of the vehicle's last message
        self._rtt: float | None = None         # wall s: smoothed round trip of a request
        self.round_trip = RoundTrip()          # vehicle s: TIMESYNC's round trip, while `timesync` is on
        self.timesync = False
        self._next_timesync = 0.0
        self._timesync_sent: deque[int] = deque(maxlen=TIMESYNC_KEEP)   # our ts1 stamps (perf_counter ns)
        conn.message_hooks.append(self._incoming)
        conn.mav.set_send_callback(self._outgoing)

    @classmethod
    def open(cls, target: str, sysid: int = 255, baud: int = 115200, rate_hint: float = 1.0,
             signing_key: bytes | None = None) -> "Session":
        """Open a pymavlink connection string (udp:/udpin:/udpout:/tcp:/serial device); LinkError if it cannot.
        With `signing_key`, see `sign()`."""
        try:
            conn = mavutil.mavlink_connection(target, baud=baud, source_system=sysid,
                                              source_component=mavlink.MAV_COMP_ID_MISSIONPLANNER,
                                              autoreconnect=True)
        except Exception as exc:         # noqa: BLE001 -- pymavlink raises anything from OSError to SerialException
            raise LinkError(f"cannot open {target}: {exc}") from None
        sock = getattr(conn, "port", None)
        if hasattr(sock, "setsockopt"):             # UDP: room for a burst of telemetry at high speedups
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RECEIVE_BUFFER)
        session = cls(conn, VehicleClock(rate_hint), target)
        if signing_key is not None:
            session.sign(signing_key)
        return session

    def sign(self, key: bytes) -> None:
        """MAVLink 2 signing with pymavlink: sign all we send (a random link id, so that another process signing
        as our sysid is another stream), and drop every frame not signed with `key` but a radio's RADIO_STATUS,
        counting them in `rejections`."""
        self.conn.setup_signing(key, sign_outgoing=True, link_id=secrets.randbelow(256),
                                allow_unsigned_callback=lambda _mav, msg_id: msg_id in UNSIGNED_RADIO)
        check_signature_first(self.conn.mav)
        self.rejections = Rejections()

    def close(self) -> None:
        self.conn.close()

    # -- identity --------------------------------------------------------------------------------------------

    def connect(self, timeout: float) -> VehicleId:
        """Wait (wall s) for a vehicle's HEARTBEAT; refuse anything but ArduSub on a sub. Our own heartbeat starts
        only with `start_heartbeats()`, once we mean to stay."""
        deadline = time.monotonic() + timeout
        next_hello = 0.0
        while time.monotonic() < deadline:
            if time.monotonic() >= next_hello:     # a TIMESYNC, so that a vehicle listening on UDP learns our
                next_hello = time.monotonic() + 0.5   # address; not a heartbeat, which would arm its GCS failsafe
                self._send_timesync()
            for msg, _ in self._receive(0.1):
                if msg.get_type() == "HEARTBEAT" and self.conn.probably_vehicle_heartbeat(msg) \
                        and msg.autopilot != mavlink.MAV_AUTOPILOT_INVALID:   # not a camera, companion, GCS
                    return self._identify(msg)
            self._check_unsigned_vehicle()
            self._check_interrupt()
        raise LinkError(f"no HEARTBEAT from a vehicle on {self.target} within {timeout:g} s: is the vehicle (or "
                        f"`rov-mav sim-bridge`) running and sending to this address?")

    def _check_unsigned_vehicle(self) -> None:
        """With a key: refuse once an autopilot's HEARTBEATs keep failing the signature check. The first ones may
        fail while a vehicle whose timestamp is far behind ours catches up from our signed hellos."""
        r = self.rejections
        if r is None or not r.vehicle_heartbeats:
            return
        now = time.monotonic()
        self._unsigned_since = self._unsigned_since or now
        if r.vehicle_heartbeats >= VEHICLE_HEARTBEATS and now - self._unsigned_since >= UNSIGNED_GRACE:
            raise LinkError(f"refusing {self.target}: {r.vehicle_heartbeats} HEARTBEATs of a vehicle were not signed "
                            f"with our key (the first: {r.first_vehicle_heartbeat.describe()}): set the key on the "
                            "vehicle (MAVProxy: `signing setup PASSPHRASE`), or run without --signing-key/"
                            "--signing-passphrase")

    def _identify(self, msg) -> VehicleId:
        if msg.type != mavlink.MAV_TYPE_SUBMARINE or msg.autopilot != mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA:
            raise LinkError(f"refusing to fly {self.target}: it is a {_enum_name('MAV_TYPE', msg.type)} on "
                            f"{_enum_name('MAV_AUTOPILOT', msg.autopilot)}, not a submarine on ArduPilot (ArduSub)")
        self.vehicle = VehicleId(msg.get_srcSystem(), msg.get_srcComponent(), msg.type, msg.autopilot)
        self.heartbeat = msg
        self.stations = StationWatch(self.vehicle.sysid)
        self.conn.target_system, self.conn.target_component = self.vehicle.sysid, self.vehicle.compid
        return self.vehicle

    @property
    def armed(self) -> bool:
        return bool(self.heartbeat.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)

    @property
    def sysid(self) -> int:
        return self.conn.mav.srcSystem

    def use_sysid(self, sysid: int) -> None:
        """Speak as `sysid` from now on (the vehicle accepts overrides only from its GCS sysid)."""
        self.conn.mav.srcSystem = sysid

    def gcs_sysid(self) -> tuple[str, int, int] | None:
        """(parameter name, value, MAV_PARAM_TYPE) of the vehicle's GCS sysid (MAV_GCS_SYSID from 4.7, else
        SYSID_MYGCS)."""
        found = self.get_params(GCS_SYSID_PARAMS, any_of=True)
        for name in GCS_SYSID_PARAMS:
            if name in found:
                return name, int(found[name][0]), found[name][1]
        return None

    def request_message(self, msg_id: int) -> None:
        """MAV_CMD_REQUEST_MESSAGE once, without waiting: one report, no stream rate changed."""
        self.fire(mavlink.MAV_CMD_REQUEST_MESSAGE, msg_id)

    # -- parameters ------------------------------------------------------------------------------------------

    def get_params(self, names, any_of: bool = False) -> dict[str, tuple[float, int]]:
        """{name: (value, MAV_PARAM_TYPE)} for those of `names` the vehicle answered (all, or the first if any_of)."""
        found: dict[str, tuple[float, int]] = {}
        sent = time.monotonic()
        for attempt, wait in enumerate(self._retries()):
            for name in names:
                if name not in found:
                    self._send("param_request_read", self.vehicle.sysid, self.vehicle.compid, name.encode(), -1)
            deadline = time.monotonic() + wait
            while time.monotonic() < deadline and len(found) < len(names) and not (any_of and found):
                for msg, _ in self._receive(min(0.05, wait)):
                    if msg.get_type() == "PARAM_VALUE" and msg.param_id in names:
                        if attempt == 0 and not found:
                            self._timed(sent)
                        found[msg.param_id] = (float(msg.param_value), int(msg.param_type))
                self._check_interrupt()
            if len(found) == len(names) or (any_of and found):
                break
        return found

    def set_param(self, name: str, value: float, ptype: int) -> bool:
        """PARAM_SET, confirmed by a PARAM_VALUE carrying the new value; False if never confirmed."""
        return not self.set_params({name: (value, ptype)})

    def set_params(self, values: dict[str, tuple[float, int]]) -> list[str]:
        """PARAM_SET of every {name: (value, MAV_PARAM_TYPE)} at once, each confirmed by a PARAM_VALUE carrying the
        new value (unconfirmed ones are sent again); returns the names never confirmed."""
        left = dict(values)
        sent = time.monotonic()
        for attempt, wait in enumerate(self._retries()):
            for name, (value, ptype) in left.items():
                self._send("param_set", self.vehicle.sysid, self.vehicle.compid, name.encode(), float(value), ptype)
            deadline = time.monotonic() + wait
            while left and (wait := deadline - time.monotonic()) > 0:
                for msg, _ in self.poll(min(wait, 0.02)):
                    if msg.get_type() == "PARAM_VALUE" and msg.param_id in left \
                            and abs(msg.param_value - left[msg.param_id][0]) < 1e-3:
                        if attempt == 0 and len(left) == len(values):
                            self._timed(sent)
                        del left[msg.param_id]
                self._check_interrupt()
            if not left:
                break
        return list(left)

    # -- commands --------------------------------------------------------------------------------------------

    def command(self, command: int, *params: float) -> int | None:
        """COMMAND_LONG, resent with its confirmation field counting up (MAVLink's command protocol) until a
        COMMAND_ACK comes; its MAV_RESULT, or None if none came. After a resend, the ACKs of the earlier sends are let
        pass before returning, so that the next command (SET_MESSAGE_INTERVAL comes in a row) cannot take one for its
        own."""
        for attempt, wait in enumerate(self._retries()):
            sent = time.monotonic()
            self.fire(command, *params, confirmation=min(attempt, MAX_CONFIRMATION))
            ack = self.wait(lambda m: m.get_type() == "COMMAND_ACK" and m.command == command, wait)
            if ack is not None:
                if attempt == 0:
                    self._timed(sent)
                else:
                    self.wait(lambda m: False, sent + wait - time.monotonic())
                return int(ack.result)
        return None

    def ask(self, send, predicate):
        """Call `send`, wait for a message matching `predicate`, call it again while the answer is late (the session's
        resend schedule); the message, or None once the retry budget is spent."""
        for attempt, wait in enumerate(self._retries()):
            sent = time.monotonic()
            send()
            reply = self.wait(predicate, wait)
            if reply is not None:
                if attempt == 0:
                    self._timed(sent)
                return reply
        return None

    def texts_since(self, t: float) -> list[str]:
        """The vehicle's STATUSTEXTs kept that came at vehicle time t or later."""
        return [text for at, text in self.texts if at >= t]

    def texts_after(self, seen: int) -> list[str]:
        """The vehicle's STATUSTEXTs kept that came after the first `seen` of them (`texts_seen`): by count, as the
        clock's extrapolation may stamp a text a little before a moment taken just ahead of it."""
        return [text for _, text in list(self.texts)[max(len(self.texts) - (self.texts_seen - seen), 0):]]

    def fire(self, command: int, *params: float, confirmation: int = 0) -> None:
        """COMMAND_LONG without waiting for its COMMAND_ACK (when the link may be gone)."""
        p = list(params) + [0.0] * (7 - len(params))
        self._send("command_long", self.vehicle.sysid, self.vehicle.compid, command, confirmation, *p)

    def announce(self, text: str) -> None:
        """STATUSTEXT (INFO) to every station on the link; ArduSub writes it to its own log
        (`GCS_MAVLINK::handle_statustext`, libraries/GCS_MAVLink/GCS_Common.cpp)."""
        self._send("statustext", mavlink.MAV_SEVERITY_INFO, text.encode()[:50])

    def send_position_target(self, position, velocity, yaw: float, acceleration=None) -> None:
        """SET_POSITION_TARGET_LOCAL_NED in MAV_FRAME_LOCAL_NED: position (m) + velocity (m/s) + yaw (rad), and the
        acceleration (m/s/s) if given; ArduSub (GCS_MAVLINK_Sub::handle_message) flies it in GUIDED with
        `guided_set_destination_posvel` (4.7.2: Guided_PosVelAccel, the acceleration fed forward)."""
        mask, accel = (POS_VEL_YAW, (0.0, 0.0, 0.0)) if acceleration is None else (POS_VEL_ACC_YAW, acceleration)
        self._send("set_position_target_local_ned", int(self.clock.now() * 1000) & 0xFFFFFFFF, self.vehicle.sysid,
                   self.vehicle.compid, mavlink.MAV_FRAME_LOCAL_NED, mask, *map(float, position),
                   *map(float, velocity), *map(float, accel), math.remainder(float(yaw), 2 * math.pi), 0.0)

    def send_position_target_terrain(self, north_east, height: float, velocity) -> bool:
        """SET_POSITION_TARGET_GLOBAL_INT in MAV_FRAME_GLOBAL_TERRAIN_ALT_INT: a point `north_east` m from the EKF
        origin (GPS_GLOBAL_ORIGIN, else HOME_POSITION; ArduPilot's flat earth) `height` m above the terrain, with the
        NED velocity (m/s); ArduSub takes it in GUIDED as a rangefinder height (PR #27767: 4.7.2 ignores it
        underwater). False (nothing sent) without an origin."""
        origin = self.origins.get("GPS_GLOBAL_ORIGIN") or self.origins.get("HOME_POSITION")
        if origin is None:
            return False
        lat, lon = lat_lon(float(north_east[0]), float(north_east[1]),
                           (origin.latitude * 1e-7, origin.longitude * 1e-7, 0.0))
        self._send("set_position_target_global_int", int(self.clock.now() * 1000) & 0xFFFFFFFF, self.vehicle.sysid,
                   self.vehicle.compid, mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT, POS_VEL, round(lat * 1e7),
                   round(lon * 1e7), float(height), *map(float, velocity), 0.0, 0.0, 0.0, 0.0, 0.0)
        return True

    def firmware_version(self, timeout: float = 3.0) -> tuple[int, int, int] | None:
        """(major, minor, patch) from AUTOPILOT_VERSION's flight_sw_version (`send_autopilot_version`), asked for
        with MAV_CMD_REQUEST_MESSAGE; None if the vehicle does not answer within `timeout` wall s."""
        self.request_message(mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
        msg = self.wait(lambda m: m.get_type() == "AUTOPILOT_VERSION", timeout)
        if msg is None:
            return None
        v = msg.flight_sw_version
        return (v >> 24) & 0xFF, (v >> 16) & 0xFF, (v >> 8) & 0xFF

    def set_mode(self, custom_mode: int) -> bool:
        """DO_SET_MODE, accepted and confirmed by a HEARTBEAT."""
        return self._confirmed((mavlink.MAV_CMD_DO_SET_MODE, mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, custom_mode),
                               lambda hb: hb.custom_mode == custom_mode)

    def arm(self, arm: bool) -> bool:
        """Arm or disarm (MAV_CMD_COMPONENT_ARM_DISARM), accepted and confirmed by a HEARTBEAT."""
        return self._confirmed((mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1.0 if arm else 0.0),
                               lambda hb: bool(hb.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED) == arm)

    def _confirmed(self, command: tuple, check) -> bool:
        """The command accepted, then a HEARTBEAT showing `check`; sent again (it is idempotent) while no heartbeat
        shows it, within the retry budget: under loss the ACK or the heartbeats may be the ones lost."""
        deadline = time.monotonic() + RETRY_BUDGET
        while True:
            if self.command(*command) != mavlink.MAV_RESULT_ACCEPTED:
                return False
            timeout = self.clock.wall_seconds(HEARTBEAT_CONFIRM * HEARTBEAT_PERIOD) + 0.5
            if self.wait(lambda m: m.get_type() == "HEARTBEAT" and self._from_vehicle(m) and check(m),
                         timeout) is not None:
                return True
            if time.monotonic() >= deadline or self._silent():
                return False

    def set_message_interval(self, msg_id: int, hz: float) -> bool:
        """MAV_CMD_SET_MESSAGE_INTERVAL (vehicle-time Hz); True if accepted. Not a parameter: nothing persists."""
        return self.command(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, msg_id, 1e6 / hz) == mavlink.MAV_RESULT_ACCEPTED

    # -- RC override -----------------------------------------------------------------------------------------

    def send_override(self, pwms) -> None:
        """RC_CHANNELS_OVERRIDE of channels 1-8 now, and hold them (resent at `override_rate` vehicle Hz)."""
        self.override = [int(round(v)) for v in pwms]
        self._send_override(self.override)

    def release_overrides(self) -> None:
        """Stop holding and hand channels 1-8 back (0 = release); channels 9-18 untouched."""
        self.override = None
        self._send_override([RELEASE] * CHANNELS)

    def _send_override(self, values: list[int]) -> None:
        fields = list(values) + [0] * (RC_FIELDS - CHANNELS)        # 9-18: 0 = leave alone
        self._send("rc_channels_override", self.vehicle.sysid, self.vehicle.compid, *fields)
        self._last_override_t = self.clock.now()
        if values[0] != RELEASE:
            self.echo.sent_now(values)

    # -- motor test ------------------------------------------------------------------------------------------

    def send_motor_test(self, pwms) -> None:
        """MAV_CMD_DO_MOTOR_TEST of motors 1-8 (board order, raw PWM) now, and hold them (resent at `override_rate`
        vehicle Hz). ArduSub runs no mixer during the test and ends it, disarming, MOTOR_TEST_TIMEOUT vehicle s after
        the last one (ArduSub/motors.cpp, `verify_motor_test`): if this process dies, the thrusters stop. Nothing is
        sent once the vehicle refused the running test or disarmed (`motor_test_stopped`)."""
        if self.motor_test_stopped is not None:
            return
        self.motor_test = [int(round(v)) for v in pwms]
        self._send_motor_test(self.motor_test)

    def _motor_test_refused(self, why: str) -> None:
        """The vehicle refused the running test or disarmed: stop sending it, for good. A disarmed ArduSub writes
        nothing to the outputs while the test runs (`Sub::motors_output` calls only `verify_motor_test`), so the last
        accepted PWMs stay on the thrusters, and every further command, refused, still stamps the test alive
        (`handle_do_motor_test` stamps first): only silence lets it time out, MOTOR_TEST_TIMEOUT after the last."""
        self.motor_test = None
        self.motor_test_stopped = (f"{why}: the run stopped sending DO_MOTOR_TEST at once (any further one, refused, "
                                   "would hold the last accepted PWMs on the thrusters); ArduSub ends the test "
                                   f"{MOTOR_TEST_TIMEOUT:g} s after the last")

    def end_motor_test(self) -> None:
        """Stop holding the motor test: ArduSub ends it (and disarms) MOTOR_TEST_TIMEOUT later."""
        self.motor_test = None

    def _send_motor_test(self, values: list[int]) -> None:
        for output, pwm in enumerate(values):
            self._send("command_long", self.vehicle.sysid, self.vehicle.compid, mavlink.MAV_CMD_DO_MOTOR_TEST, 0,
                       output, MOTOR_TEST_PWM, pwm, MOTOR_TEST_TIMEOUT, 0, MOTOR_TEST_BOARD, 0)
        self._last_motor_test_t = self.clock.now()

    # -- pumping ---------------------------------------------------------------------------------------------

    def poll(self, timeout: float) -> list[tuple[object, float]]:
        """Messages from the vehicle received within `timeout` wall s, each with its wall arrival time
        (perf_counter); sends the heartbeat and the held override when due."""
        out = [(m, w) for m, w in self._receive(timeout) if self._from_vehicle(m)]
        self.service()
        return out

    def wait(self, predicate, timeout: float):
        """The first message from the vehicle satisfying `predicate` within `timeout` wall s, else None."""
        deadline = time.monotonic() + timeout
        while (left := deadline - time.monotonic()) > 0:
            for msg, _ in self.poll(min(left, 0.02)):
                if predicate(msg):
                    return msg
            self._check_interrupt()
        return None

    def start_heartbeats(self) -> None:
        """Send the GCS heartbeat from now on (1 Hz of vehicle time, and at least 1 Hz of wall time)."""
        self.heartbeats = True
        self.service()

    def service(self) -> None:
        """Send the GCS heartbeat, the held override and the held motor test if they are due in vehicle time."""
        now = self.clock.now()
        if self.rejections is not None:
            advance(self.conn.mav.signing, time.time())
        if self.heartbeats and (now >= self._next_heartbeat
                                or time.perf_counter() - self._wall_last_heartbeat >= HEARTBEAT_PERIOD):
            self._send_heartbeat()
            self._next_heartbeat = now + HEARTBEAT_PERIOD
        if self.override is not None and now - self._last_override_t >= 1.0 / self.override_rate:
            self._send_override(self.override)
        if self.motor_test is not None and now - self._last_motor_test_t >= 1.0 / self.override_rate:
            self._send_motor_test(self.motor_test)
        if self.timesync and now >= self._next_timesync:
            self._send_timesync()
            self._next_timesync = now + TIMESYNC_PERIOD

    def _send_timesync(self) -> None:
        """A TIMESYNC request stamped with our clock (ts1); ArduPilot answers it on the same link at once, ts1
        echoed and tc1 its own time (GCS_MAVLINK::handle_timesync, libraries/GCS_MAVLink/GCS_Common.cpp)."""
        stamp = time.perf_counter_ns()
        self._timesync_sent.append(stamp)
        self._send("timesync", 0, stamp)

    def _timesync_answer(self, msg) -> None:
        """The vehicle's answer to one of our requests: a round-trip sample, in vehicle seconds."""
        if msg.tc1 != 0 and msg.ts1 in self._timesync_sent:
            self._timesync_sent.remove(msg.ts1)
            self.round_trip.add((time.perf_counter_ns() - msg.ts1) * 1e-9 * self.clock.rate)

    def _send_heartbeat(self) -> None:
        self._send("heartbeat", mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, mavlink.MAV_STATE_ACTIVE)
        self._wall_last_heartbeat = time.perf_counter()

    def _retries(self) -> Iterator[float]:
        """Wall s to wait after each send of a request: the first always, then growing waits until the budget is
        spent or the vehicle has gone silent."""
        start = time.monotonic()
        for attempt in itertools.count():
            first = RETRY_FIRST if self._rtt is None else min(max(RTT_MARGIN * self._rtt, RETRY_MIN), RETRY_FIRST)
            left = RETRY_BUDGET - (time.monotonic() - start)
            yield min(first * RETRY_GROWTH ** attempt, RETRY_LONGEST, max(left, RETRY_MIN))
            if time.monotonic() - start >= RETRY_BUDGET or self._silent():
                return

    def _timed(self, sent: float) -> None:
        """A request sent at `sent` answered before any resend: a round-trip sample (resent ones are ambiguous)."""
        sample = time.monotonic() - sent
        self._rtt = sample if self._rtt is None else (1 - RTT_GAIN) * self._rtt + RTT_GAIN * sample

    def _silent(self) -> bool:
        return time.monotonic() - self._heard > SILENCE

    def _check_interrupt(self) -> None:
        if self.interrupt is not None:
            self.interrupt()

    def _send(self, name: str, *fields) -> None:
        try:
            getattr(self.conn.mav, f"{name}_send")(*fields)
        except OSError:
            pass                           # a dead link shows as silence, which the watchdog handles

    def _receive(self, timeout: float) -> list[tuple[object, float]]:
        out = []
        if self.conn.select(timeout):
            while True:
                try:
                    msg = self.conn.recv_msg()
                except (OSError, mavlink.MAVError):
                    break
                if msg is None:
                    break
                if msg.get_type() != "BAD_DATA":
                    out.append((msg, time.perf_counter()))
        return out

    def _from_vehicle(self, msg) -> bool:
        v = self.vehicle
        return v is not None and msg.get_srcSystem() == v.sysid and msg.get_srcComponent() == v.compid

    def _incoming(self, _conn, msg) -> None:
        kind = msg.get_type()
        if kind == "BAD_DATA":
            if self.rejections is not None:
                self.rejections.note(msg)
            return
        for tap in self.taps:
            tap(msg, False)
        if self.vehicle is None:
            return
        if self._from_vehicle(msg):
            self._heard = time.monotonic()
            boot_ms = getattr(msg, "time_boot_ms", None)
            if boot_ms is not None:
                self.clock.observe(boot_ms / 1000.0)
            if kind == "HEARTBEAT":
                self.heartbeat = msg
                if self.motor_test is not None and self.motor_test_answers["accepted"] and not self.armed:
                    self._motor_test_refused("the vehicle disarmed during the motor test")
            elif kind in ("GPS_GLOBAL_ORIGIN", "HOME_POSITION"):
                self.origins[kind] = msg
            elif kind == "TIMESYNC":
                self._timesync_answer(msg)
            elif kind == "STATUSTEXT":
                self.texts.append((self.clock.now(), msg.text))
                self.texts_seen += 1
            elif kind == "COMMAND_ACK" and msg.command == mavlink.MAV_CMD_DO_MOTOR_TEST:
                answer = "accepted" if msg.result == mavlink.MAV_RESULT_ACCEPTED else "refused"
                if answer == "refused" and self.motor_test is not None and self.motor_test_answers["accepted"]:
                    self._motor_test_refused(f"the vehicle refused the running motor test (MAV_RESULT {msg.result})")
                self.motor_test_answers[answer] += 1
        else:
            self.stations.observe(msg, self.clock.now())

    def _outgoing(self, msg) -> None:
        for tap in self.taps:
            tap(msg, True)
