"""The vehicle's stored mission and the MAVLink mission protocol that fills and reads it, as ArduSub 4.5 does.

The state machine is libraries/GCS_MAVLink/MissionItemProtocol.cpp; what the mission keeps is
MissionItemProtocol_Waypoints.cpp and AP_Mission (`mavlink_int_to_mission_cmd`, `mission_cmd_to_mavlink_int`,
`stored_in_location`). Checked against ArduSub 4.5.3 SITL:
- Upload: MISSION_COUNT cuts the stored mission to that many items and asks for each with MISSION_REQUEST (4.5 asks
  with MISSION_REQUEST, not _INT), from item 0 (home's slot: stored, but reading item 0 always gives the current
  home). A request goes out again after 1 s without the item; 8 s without one cancel the upload
  ("Mission upload timeout", MISSION_ACK OPERATION_CANCELLED). After the last item: "Flight plan received" and
  MISSION_ACK ACCEPTED (a count of 0 gets them at once). An item out of sequence is answered INVALID_SEQUENCE and
  the upload goes on; one the mission cannot hold (unknown command, frame, latitude, longitude, altitude, a jump to
  nowhere) ends it with that result. While an upload runs, another station's MISSION_COUNT and every download
  request are DENIED, MISSION_CLEAR_ALL gets ERROR.
- Download: MISSION_REQUEST_LIST -> MISSION_COUNT (0 until a mission is stored: home is not counted then);
  MISSION_REQUEST_INT -> MISSION_ITEM_INT (MISSION_REQUEST -> MISSION_ITEM, and a warning text); past the end ->
  MISSION_COUNT and MISSION_ACK ERROR.
- What an item keeps: a NAV_WAYPOINT its hold time in whole seconds and nothing of param2-4 (its yaw is lost); a
  NAV_LOITER_TIME its time and turn direction; a positioned item its altitude in whole cm and its frame as
  GLOBAL_RELATIVE_ALT (3) / GLOBAL (0) / TERRAIN (10), whichever _INT twin it came in; an item without a position
  comes back with frame 0 and no x, y, z; the others keep their params (as float32).
- MISSION_CURRENT (EXT_STAT stream, `telemetry.mission_current`) counts the items stored here.
Other mission types (fence, rally) are not kept here: UNSUPPORTED, as for a vehicle without them.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sim_bridge.gcs.telemetry import ENCODER

MISSION = mavlink.MAV_MISSION_TYPE_MISSION
UPLOAD_TIMEOUT = 8.0              # s without an item (MissionItemProtocol::upload_timeout_ms)
REQUEST_RESEND = 1.0              # s before a request is repeated (wp_recv_timeout_ms, no stream slowdown)
MAX_ITEMS = 724                   # chosen: the mission storage of a 16 kB board holds about this many
LOCATION_ALT_MAX_M = 83000        # AP_Common/Location.h
INFO, WARNING = mavlink.MAV_SEVERITY_INFO, mavlink.MAV_SEVERITY_WARNING
# Commands AP_Mission::mavlink_int_to_mission_cmd knows (any other: UNSUPPORTED), and those stored with a position.
KNOWN = {getattr(mavlink, f"MAV_CMD_{name}") for name in (
    "NAV_WAYPOINT", "NAV_LOITER_UNLIM", "NAV_LOITER_TURNS", "NAV_LOITER_TIME", "NAV_RETURN_TO_LAUNCH", "NAV_LAND",
    "NAV_TAKEOFF", "NAV_CONTINUE_AND_CHANGE_ALT", "NAV_LOITER_TO_ALT", "NAV_SPLINE_WAYPOINT", "NAV_GUIDED_ENABLE",
    "NAV_DELAY", "NAV_ALTITUDE_WAIT", "NAV_VTOL_TAKEOFF", "NAV_VTOL_LAND", "NAV_PAYLOAD_PLACE", "NAV_SET_YAW_SPEED",
    "CONDITION_DELAY", "CONDITION_DISTANCE", "CONDITION_YAW", "DO_SET_MODE", "DO_JUMP", "DO_CHANGE_SPEED",
    "DO_SET_HOME", "DO_SET_RELAY", "DO_REPEAT_RELAY", "DO_SET_SERVO", "DO_REPEAT_SERVO", "DO_LAND_START",
    "DO_GO_AROUND", "DO_SET_ROI", "DO_DIGICAM_CONFIGURE", "DO_DIGICAM_CONTROL", "DO_MOUNT_CONTROL",
    "DO_SET_CAM_TRIGG_DIST", "DO_FENCE_ENABLE", "DO_PARACHUTE", "DO_INVERTED_FLIGHT", "DO_GRIPPER",
    "DO_GUIDED_LIMITS", "DO_AUTOTUNE_ENABLE", "DO_VTOL_TRANSITION", "DO_SET_REVERSE", "DO_ENGINE_CONTROL",
    "DO_WINCH", "DO_SET_RESUME_REPEAT_DIST", "IMAGE_START_CAPTURE", "IMAGE_STOP_CAPTURE", "VIDEO_START_CAPTURE",
    "VIDEO_STOP_CAPTURE", "CONDITION_GATE")}
POSITIONED = {getattr(mavlink, f"MAV_CMD_{name}") for name in (
    "NAV_WAYPOINT", "NAV_LOITER_UNLIM", "NAV_LOITER_TURNS", "NAV_LOITER_TIME", "NAV_LAND", "NAV_TAKEOFF",
    "NAV_CONTINUE_AND_CHANGE_ALT", "NAV_LOITER_TO_ALT", "NAV_SPLINE_WAYPOINT", "NAV_GUIDED_ENABLE", "DO_SET_HOME",
    "DO_LAND_START", "DO_GO_AROUND", "DO_SET_ROI", "NAV_VTOL_TAKEOFF", "NAV_VTOL_LAND", "NAV_PAYLOAD_PLACE")}
# Frame a positioned item may come in -> the frame it is read back in.
FRAMES = {0: 0, 2: 0, 5: 0, 3: 3, 6: 3, 10: 10, 11: 10}

Reply = tuple[object, bool]


@dataclass(frozen=True)
class Item:
    """One stored item as it reads back: MISSION_ITEM_INT's frame, command, param1-4, x, y (1e-7 deg), z (m)."""

    frame: int
    command: int
    params: tuple[float, float, float, float]
    x: int
    y: int
    z: float


class MissionProtocol:
    """The stored mission of one vehicle and its upload in progress. `home()` gives (lat deg, lon deg, alt m)."""

    def __init__(self, home: Callable[[], tuple[float, float, float]]):
        self.home = home
        self.items: list[Item] = []
        self.receiving = False
        self.channel = 0                  # the link of the upload in progress
        self._dest = (0, 0)               # (sysid, compid) of the uploading station
        self._next = 0                    # the item asked for
        self._last = 0
        self._received_t = 0.0
        self._requested_t = 0.0
        self._warned_item = False         # one warning per upload sent with MISSION_ITEM

    # -- messages --------------------------------------------------------------------------------------------

    def handle(self, msg, channel: int, t: float) -> list[Reply]:
        """Replies (on the link `msg` came in on) to a MISSION_* message received at sim time t."""
        kind = msg.get_type()
        if getattr(msg, "mission_type", MISSION) != MISSION:
            return [] if kind == "MISSION_ACK" else [self._ack(msg, mavlink.MAV_MISSION_UNSUPPORTED)]
        if kind == "MISSION_ITEM" and self.receiving and not self._warned_item:
            self._warned_item = True
            return [(_text(WARNING, "got MISSION_ITEM; GCS should send MISSION_ITEM_INT"), False),
                    *self._item(msg, t)]
        if kind == "MISSION_COUNT":
            return self._count(msg, channel, t)
        if kind in ("MISSION_ITEM_INT", "MISSION_ITEM"):
            return self._item(msg, t)
        if kind == "MISSION_REQUEST_LIST":
            if self.receiving:
                return [self._ack(msg, mavlink.MAV_MISSION_DENIED)]
            return [(ENCODER.mission_count_encode(*_source(msg), len(self.items), MISSION), False)]
        if kind in ("MISSION_REQUEST_INT", "MISSION_REQUEST"):
            return self._request(msg)
        if kind == "MISSION_CLEAR_ALL":
            if self.receiving:
                return [self._ack(msg, mavlink.MAV_MISSION_ERROR)]
            self.items = []
            return [self._ack(msg, mavlink.MAV_MISSION_ACCEPTED)]
        return []

    def update(self, t: float) -> list[tuple[int, object]]:
        """(channel, message) to send at sim time t: a late request again, or the upload's cancellation."""
        if not self.receiving:
            return []
        if t - self._received_t > UPLOAD_TIMEOUT:
            self.receiving = False
            return [(self.channel, _text(WARNING, "Mission upload timeout")),
                    (self.channel, ENCODER.mission_ack_encode(*self._dest, mavlink.MAV_MISSION_OPERATION_CANCELLED,
                                                              MISSION))]
        if t - self._requested_t > REQUEST_RESEND:
            return [(self.channel, self._ask(t))]
        return []

    # -- upload ----------------------------------------------------------------------------------------------

    def _count(self, msg, channel: int, t: float) -> list[Reply]:
        if self.receiving and _source(msg) != self._dest:
            return [self._ack(msg, mavlink.MAV_MISSION_DENIED)]
        if msg.count > MAX_ITEMS:
            return [self._ack(msg, mavlink.MAV_MISSION_NO_SPACE),
                    (_text(WARNING, f"Only {MAX_ITEMS} items are supported"), False)]
        del self.items[msg.count:]
        if msg.count == 0:
            self.receiving = False
            return self._complete(msg)
        self.receiving, self.channel, self._dest, self._warned_item = True, channel, _source(msg), False
        self._next, self._last, self._received_t = 0, msg.count - 1, t
        return [(self._ask(t), False)]

    def _item(self, msg, t: float) -> list[Reply]:
        if not self.receiving:
            return []
        if msg.seq != self._next:
            return [self._ack(msg, mavlink.MAV_MISSION_INVALID_SEQUENCE)]
        if _source(msg) != self._dest:
            return [self._ack(msg, mavlink.MAV_MISSION_DENIED)]
        result, item = self._stored(msg)
        if result == mavlink.MAV_MISSION_ACCEPTED and msg.seq > len(self.items):
            result = mavlink.MAV_MISSION_ERROR
        if result != mavlink.MAV_MISSION_ACCEPTED:
            self.receiving = False
            return [self._ack(msg, result)]
        if msg.seq < len(self.items):
            self.items[msg.seq] = item
        else:
            self.items.append(item)
        self._received_t = t
        self._next += 1
        if self._next > self._last:
            self.receiving = False
            return self._complete(msg)
        return [(self._ask(t), False)]

    def _stored(self, msg) -> tuple[int, Item | None]:
        """(MAV_MISSION_RESULT, the item as AP_Mission keeps it) of a MISSION_ITEM(_INT)."""
        command = msg.command
        if command not in KNOWN:
            return mavlink.MAV_MISSION_UNSUPPORTED, None
        if msg.get_type() == "MISSION_ITEM":
            if command in POSITIONED and not (abs(msg.x) <= 90 and abs(msg.y) <= 180):
                return mavlink.MAV_MISSION_INVALID_PARAM5_X if abs(msg.x) > 90 else \
                    mavlink.MAV_MISSION_INVALID_PARAM6_Y, None
            x, y = int(msg.x * 1e7), int(msg.y * 1e7)
        else:
            x, y = msg.x, msg.y
        p = tuple(float(np.float32(v)) for v in (msg.param1, msg.param2, msg.param3, msg.param4))
        if command == mavlink.MAV_CMD_DO_JUMP and (p[0] == 0 or (p[0] >= len(self.items) and p[0] > self._last)):
            return mavlink.MAV_MISSION_ERROR, None
        if command not in POSITIONED:
            return mavlink.MAV_MISSION_ACCEPTED, Item(0, command, p, 0, 0, 0.0)
        if abs(x) > 900_000_000:
            return mavlink.MAV_MISSION_INVALID_PARAM5_X, None
        if abs(y) > 1_800_000_000:
            return mavlink.MAV_MISSION_INVALID_PARAM6_Y, None
        if math.isnan(msg.z) or abs(msg.z) >= LOCATION_ALT_MAX_M:
            return mavlink.MAV_MISSION_INVALID_PARAM7, None
        if msg.frame not in FRAMES:
            return mavlink.MAV_MISSION_UNSUPPORTED_FRAME, None
        if command == mavlink.MAV_CMD_NAV_WAYPOINT:
            p = (_uint16(p[0]), 0.0, 0.0, 0.0)
        elif command == mavlink.MAV_CMD_NAV_LOITER_TIME:
            p = (_uint16(p[0]), 0.0, -1.0 if p[2] < 0 else 1.0, 1.0 if p[3] > 0 else 0.0)
        z = math.trunc(msg.z * 100.0) / 100.0
        return mavlink.MAV_MISSION_ACCEPTED, Item(FRAMES[msg.frame], command, p, x, y, z)

    def _ask(self, t: float):
        self._requested_t = t
        return ENCODER.mission_request_encode(*self._dest, self._next, MISSION)

    def _complete(self, msg) -> list[Reply]:
        return [(_text(INFO, "Flight plan received"), False), self._ack(msg, mavlink.MAV_MISSION_ACCEPTED)]

    # -- download --------------------------------------------------------------------------------------------

    def _request(self, msg) -> list[Reply]:
        if self.receiving:
            return [self._ack(msg, mavlink.MAV_MISSION_DENIED)]
        count = len(self.items)
        if msg.seq != 0 and msg.seq >= count:
            return [(ENCODER.mission_count_encode(*_source(msg), count, MISSION), False),
                    self._ack(msg, mavlink.MAV_MISSION_ERROR)]
        item = self._home() if msg.seq == 0 else self.items[msg.seq]
        if msg.get_type() == "MISSION_REQUEST_INT":
            return [(ENCODER.mission_item_int_encode(*_source(msg), msg.seq, item.frame, item.command, 0, 1,
                                                     *item.params, item.x, item.y, item.z, MISSION), False)]
        return [(ENCODER.mission_item_encode(*_source(msg), msg.seq, item.frame, item.command, 0, 1, *item.params,
                                             item.x / 1e7, item.y / 1e7, item.z, MISSION), False),
                (_text(WARNING, "got MISSION_REQUEST; use MISSION_REQUEST_INT!"), False)]

    def _home(self) -> Item:
        lat, lon, alt = self.home()
        return Item(0, mavlink.MAV_CMD_NAV_WAYPOINT, (0.0, 0.0, 0.0, 0.0), round(lat * 1e7), round(lon * 1e7),
                    float(alt))

    @staticmethod
    def _ack(msg, result: int) -> Reply:
        return ENCODER.mission_ack_encode(*_source(msg), result, getattr(msg, "mission_type", MISSION)), False


def _source(msg) -> tuple[int, int]:
    return msg.get_srcSystem(), msg.get_srcComponent()


def _text(severity: int, text: str):
    return ENCODER.statustext_encode(severity, text.encode()[:50])


def _uint16(value: float) -> float:
    """A float param stored in AP_Mission's uint16 p1 (C's truncation; out of range clamped here)."""
    return float(min(max(math.trunc(value), 0), 65535)) if math.isfinite(value) else 0.0
