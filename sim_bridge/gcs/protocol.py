"""What the emulated ArduSub answers to each MAVLink message a ground station sends (its GCS_MAVLINK layer).

`Protocol.handle(msg, channel, scheduler, t)` returns the replies as (message, to_all) pairs: to_all=True goes out on
every link (PARAM_VALUE after a PARAM_SET), False only back on the link the request came in on. The parameter list a
PARAM_REQUEST_LIST asks for is streamed, not sent at once (`queued_params`), as `GCS_MAVLINK::queued_param_send`
sends a few each pass of the main loop: a burst of hundreds of datagrams overflows a slow reader's socket.
"""

from __future__ import annotations

import struct
from collections.abc import Callable

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sim_bridge.autopilot import arming

from sim_bridge.gcs import schedule, telemetry
from sim_bridge.autopilot.ardusub import (
    MAV_RESULT_ACCEPTED,
    MAV_RESULT_DENIED,
    MAV_RESULT_FAILED,
    MAV_RESULT_UNSUPPORTED,
    MAV_SEVERITY_INFO,
    ArduSub,
)
from sim_bridge.gcs.missions import MissionProtocol
from sim_bridge.hardware.numeric import float_to_int, is_equal, is_zero, wrap
from sim_bridge.autopilot.params import NO_STREAM_OVERRIDE, STREAM_GROUPS, Params
from sim_bridge.gcs.schedule import Scheduler
from sim_bridge.gcs.signing import ARMED_REFUSAL, VehicleSigning
from sim_bridge.gcs.telemetry import ENCODER, Snapshot

Reply = tuple[object, bool]
MISSION_MESSAGES = ("MISSION_COUNT", "MISSION_ITEM_INT", "MISSION_ITEM", "MISSION_REQUEST_LIST", "MISSION_REQUEST_INT",
                    "MISSION_REQUEST", "MISSION_CLEAR_ALL", "MISSION_ACK")
UINT16_MAX = 65535
FTP_ACK, FTP_NAK = 128, 129
FTP_TERMINATE, FTP_RESET, FTP_LIST, FTP_OPEN_RO = 1, 2, 3, 4
FTP_ERR_UNKNOWN_COMMAND, FTP_ERR_FILE_NOT_FOUND = 7, 10
COMPID = 1
FORCE_REBOOT = 20190226          # the magic that reboots an armed vehicle (PR #22325)
PARAMS_PER_SECOND = 400.0        # of vehicle time: a parameter list streamed at ArduSub's pace over a tether (about
                                 # 900 in 2-3 s into QGroundControl); one or two a pass of the 400 Hz loop


class Protocol:
    """Dispatches incoming messages to the vehicle, the parameters, the stored mission and the link's scheduler."""

    def __init__(self, vehicle: ArduSub, params: Params, snapshot: Callable[[], Snapshot],
                 on_params_changed: Callable[[float], None], missions: MissionProtocol,
                 signing: VehicleSigning | None = None):
        self.vehicle = vehicle
        self.params = params
        self.missions = missions
        self.snapshot = snapshot
        self.on_params_changed = on_params_changed
        self.signing = signing
        self.reboot_requested = False          # by MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN, for the bridge to act on
        self.on_param_set: Callable[[str, float, float], None] | None = None   # (name, stored value, t)
        self._param_lists: dict[int, tuple[float, int]] = {}   # link -> (t the list was asked for, parameters sent)

    def handle(self, msg, channel: int, scheduler: Scheduler, t: float) -> list[Reply]:
        """Replies to one message received on link `channel` at sim time t (one routing kept for this vehicle)."""
        kind = msg.get_type()
        sysid = msg.get_srcSystem()
        if kind == "HEARTBEAT":
            self.vehicle.gcs_heartbeat(sysid, t)
        elif kind == "RC_CHANNELS_OVERRIDE":
            self.vehicle.rc_override(sysid, [getattr(msg, f"chan{i}_raw") for i in range(1, 19)], t)
        elif kind == "MANUAL_CONTROL":
            self.vehicle.manual_control(sysid, msg.target, (msg.x, msg.y, msg.z, msg.r, msg.s, msg.t), t,
                                        msg.buttons | (getattr(msg, "buttons2", 0) or 0) << 16)
        elif kind == "SET_POSITION_TARGET_LOCAL_NED":
            self.vehicle.position_target(msg.coordinate_frame, msg.type_mask, (msg.x, msg.y, msg.z),
                                         (msg.vx, msg.vy, msg.vz), msg.yaw, t, (msg.afx, msg.afy, msg.afz),
                                         msg.yaw_rate)
        elif kind == "SET_POSITION_TARGET_GLOBAL_INT":
            self.vehicle.position_target_global(msg.coordinate_frame, msg.type_mask, msg.lat_int * 1e-7,
                                                msg.lon_int * 1e-7, msg.alt, (msg.vx, msg.vy, msg.vz), t)
        elif kind == "DISTANCE_SENSOR":        # `GCS_MAVLINK::handle_distance_sensor`: from anyone, to the rangefinder
            self.vehicle.rangefinder.handle(msg.orientation, msg.current_distance, msg.min_distance, msg.max_distance,
                                            msg.signal_quality, msg.type, t)
        elif kind in ("COMMAND_LONG", "COMMAND_INT"):
            return self._command(msg, scheduler, t)
        elif kind == "SET_MODE":
            result = self._set_mode(msg.base_mode, msg.custom_mode)
            return [(ENCODER.command_ack_encode(mavlink.MAVLINK_MSG_ID_SET_MODE, result, 0, 0, sysid,
                                                msg.get_srcComponent()), False)]
        elif kind == "PARAM_REQUEST_LIST":      # `handle_param_request_list` sends the banner first
            self._param_lists[channel] = (t, 0)   # a new request starts the list again
            return self._banner()
        elif kind == "PARAM_REQUEST_READ":
            return self._param_read(msg)
        elif kind == "PARAM_SET":
            return self._param_set(msg, t)
        elif kind == "REQUEST_DATA_STREAM":
            self._request_data_stream(msg, channel, t)
        elif kind == "TIMESYNC" and msg.tc1 == 0:
            return [(ENCODER.timesync_encode(int(t * 1e9), msg.ts1), False)]
        elif kind == "FILE_TRANSFER_PROTOCOL":
            return [(self._ftp_refusal(msg), False)]
        elif kind == "SETUP_SIGNING" and self.signing is not None:
            self._setup_signing(msg, channel)
        elif kind in MISSION_MESSAGES:
            return self.missions.handle(msg, channel, t)
        return []

    def _setup_signing(self, msg, channel: int) -> None:
        """`GCS_MAVLINK::handle_setup_signing`: refused while armed (a STATUSTEXT says so), else the key and its
        initial timestamp stored and applied on every link; no reply."""
        if self.vehicle.armed:
            self.vehicle.texts.append((mavlink.MAV_SEVERITY_ERROR, ARMED_REFUSAL))
            return
        self.signing.setup(bytes(msg.secret_key), msg.initial_timestamp,
                           f"{msg.get_srcSystem()}/{msg.get_srcComponent()} on link {channel}")

    # -- commands --------------------------------------------------------------------------------------------

    def _command(self, msg, scheduler: Scheduler, t: float) -> list[Reply]:
        """COMMAND_LONG and COMMAND_INT alike (ArduPilot runs a COMMAND_LONG as a COMMAND_INT:
        `GCS_MAVLINK::try_command_long_as_command_int`), each parameter cast as GCS_Common.cpp casts it; the
        COMMAND_ACK follows a MESSAGE_INTERVAL answer and precedes a requested message, as ArduSub sends them."""
        cmd, p1, p2 = msg.command, msg.param1, msg.param2
        before: list[Reply] = []
        after: list[Reply] = []
        if cmd == mavlink.MAV_CMD_COMPONENT_ARM_DISARM:
            result = self._arm_disarm(p1, p2)
        elif cmd == mavlink.MAV_CMD_DO_SET_MODE:
            result = self._set_mode(float_to_int(p1), float_to_int(p2, signed=False))
        elif cmd == mavlink.MAV_CMD_SET_MESSAGE_INTERVAL:
            result = self._set_interval(float_to_int(p1, signed=False), float_to_int(p2), scheduler, t)
        elif cmd == mavlink.MAV_CMD_GET_MESSAGE_INTERVAL:
            result, reply = self._get_interval(float_to_int(p1, signed=False), scheduler)
            before.append((reply, False))
        elif cmd == mavlink.MAV_CMD_REQUEST_MESSAGE:
            result, after = self._request_message(float_to_int(p1, signed=False))
        elif cmd == mavlink.MAV_CMD_DO_MOTOR_TEST:          # param6 becomes COMMAND_INT's int32 y
            y = msg.y if msg.get_type() == "COMMAND_INT" else float_to_int(msg.param6)
            result = self.vehicle.motor_test(p1, p2, msg.param3, y, t)
        elif cmd == mavlink.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN:       # param6 becomes COMMAND_INT's int32 y
            y = msg.y if msg.get_type() == "COMMAND_INT" else float_to_int(msg.param6)
            result = self._reboot(msg.target_component, p1, p2, msg.param3, y)
        elif cmd == mavlink.MAV_CMD_DO_SEND_BANNER:
            result, after = MAV_RESULT_ACCEPTED, self._banner()
        elif cmd == mavlink.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES:
            result, after = (self._request_message(mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION) if is_equal(p1, 1.0)
                             else (MAV_RESULT_FAILED, []))
        else:
            result = MAV_RESULT_UNSUPPORTED
        ack = ENCODER.command_ack_encode(cmd, result, 0, 0, msg.get_srcSystem(), msg.get_srcComponent())
        return before + [(ack, False)] + after

    def _banner(self) -> list[Reply]:
        return [(ENCODER.statustext_encode(MAV_SEVERITY_INFO, text.encode()), False)
                for text in telemetry.banner(self.params.firmware, self.vehicle.frame)]

    def _reboot(self, target_component: int, p1: float, p2: float, p3: float, y: int) -> int:
        """`GCS_MAVLINK::handle_preflight_reboot`: DENIED for another component; the 42/24/71 test actions are not
        emulated (UNSUPPORTED); FAILED while armed unless y (COMMAND_LONG param6) is 20190226; param1 1 (reboot) or
        3 (a board would stay in its bootloader; this vehicle reboots, as SITL does) is ACCEPTED and `reboot_requested`
        set, for the bridge to
        cut the power once the ACK is out; anything else UNSUPPORTED."""
        if target_component not in (0, COMPID):
            return MAV_RESULT_DENIED
        if is_equal(p1, 42.0) and is_equal(p2, 24.0) and is_equal(p3, 71.0):
            return MAV_RESULT_UNSUPPORTED
        if self.vehicle.armed and y != FORCE_REBOOT:
            return MAV_RESULT_FAILED
        if not (is_equal(p1, 1.0) or is_equal(p1, 3.0)):
            return MAV_RESULT_UNSUPPORTED
        self.reboot_requested = True
        return MAV_RESULT_ACCEPTED

    def _arm_disarm(self, param1: float, param2: float) -> int:
        """`GCS_MAVLINK::handle_command_component_arm_disarm`: param1 equal to 1 (within float32's epsilon) arms,
        with the arming checks unless param2 is `magic_force_arm_value` (`sim_bridge.autopilot.arming`); zero disarms;
        anything else (NaN too) is UNSUPPORTED."""
        if is_equal(param1, 1.0):
            return self.vehicle.arm(True, checks=not is_equal(param2, arming.FORCE_ARM))
        if is_zero(param1):
            return self.vehicle.arm(False)
        return MAV_RESULT_UNSUPPORTED

    def _set_interval(self, msg_id: int, interval_us: int, scheduler: Scheduler, t: float) -> int:
        """`GCS_MAVLINK::set_message_interval`: DENIED, with ArduPilot's notice, for a message this vehicle does not
        send."""
        name = telemetry.NAME_OF_ID.get(msg_id)
        if name is None:
            self.vehicle.texts.append((MAV_SEVERITY_INFO, f"No ap_message for mavlink id ({msg_id})"))
            return MAV_RESULT_DENIED
        scheduler.set_interval(name, interval_us, t)
        return MAV_RESULT_ACCEPTED

    @staticmethod
    def _get_interval(msg_id: int, scheduler: Scheduler):
        """`GCS_MAVLINK::handle_command_get_message_interval`: (MAV_RESULT, MESSAGE_INTERVAL); interval 0 = not
        available (FAILED, also for ids past uint16, reported truncated), -1 = not sent, else the interval in us."""
        name = telemetry.NAME_OF_ID.get(msg_id)
        if name is None:
            return MAV_RESULT_FAILED, ENCODER.message_interval_encode(msg_id & 0xFFFF, 0)
        interval = scheduler.intervals[name]
        return MAV_RESULT_ACCEPTED, ENCODER.message_interval_encode(msg_id, round(interval * 1e6) if interval else -1)

    def _request_message(self, msg_id: int) -> tuple[int, list[Reply]]:
        """`GCS_MAVLINK::handle_command_request_message`: the message once, or FAILED for one this vehicle does not
        send (ACCEPTED and nothing, as ArduPilot's `try_send_message`, for one it cannot fill now, such as
        LOCAL_POSITION_NED without a position)."""
        name = telemetry.NAME_OF_ID.get(msg_id)
        if name is None:
            return MAV_RESULT_FAILED, []
        msg = telemetry.BUILDERS[name](self.snapshot())          # None: not available now (ACCEPTED, not sent)
        return MAV_RESULT_ACCEPTED, [] if msg is None else [(msg, False)]

    def _set_mode(self, base_mode: int, custom_mode: int) -> int:
        """`GCS_MAVLINK::_set_mode_common`: with the custom-mode flag, the custom mode as the uint8_t
        `Sub::set_mode` takes (FAILED if it cannot be entered); base_mode 128 alone works the safety switch (custom
        mode 0 off, 1 on, else DENIED); anything else is DENIED."""
        if (base_mode & 0xFFFFFFFF) & mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
            return MAV_RESULT_ACCEPTED if self.vehicle.set_mode(custom_mode & 0xFF) else MAV_RESULT_FAILED
        if base_mode == mavlink.MAV_MODE_FLAG_DECODE_POSITION_SAFETY and custom_mode in (0, 1):
            self.vehicle.set_safety(custom_mode == 1)
            return MAV_RESULT_ACCEPTED
        return MAV_RESULT_DENIED

    # -- parameters ------------------------------------------------------------------------------------------

    def queued_params(self, channel: int, t: float) -> list:
        """The PARAM_VALUEs of the list link `channel` asked for that are due at vehicle time t, in index order."""
        if channel not in self._param_lists:
            return []
        start, sent = self._param_lists[channel]
        due = min(len(self.params), int((t - start) * PARAMS_PER_SECOND) + 1)
        if due >= len(self.params):
            del self._param_lists[channel]
        else:
            self._param_lists[channel] = (start, max(due, sent))
        return [self._param_value(i) for i in range(sent, due)]

    def _param_value(self, index: int, reported_index: int | None = None):
        spec = self.params.specs[index]
        return ENCODER.param_value_encode(spec.name.encode(), self.params[spec.name], spec.ptype, len(self.params),
                                          index if reported_index is None else reported_index)

    def _param_read(self, msg) -> list[Reply]:
        """By index unless the index is -1 (then by name, answered with index -1 as 65535: ArduPilot echoes the
        request's index, measured on ArduSub 4.5.3 SITL), as `GCS_MAVLINK::handle_param_request_read`; no reply
        when there is no such parameter."""
        if msg.param_index != -1:
            if 0 <= msg.param_index < len(self.params):
                return [(self._param_value(msg.param_index), False)]
            return []
        name = _param_name(msg.param_id)
        return [(self._param_value(self.params.index(name), reported_index=UINT16_MAX), False)] \
            if name in self.params else []

    def _param_set(self, msg, t: float) -> list[Reply]:
        name = _param_name(msg.param_id)
        if (stored := self.params.set(name, msg.param_value)) is None:
            return []
        self.on_params_changed(t)
        if self.on_param_set is not None:
            self.on_param_set(name, stored, t)
        return [(self._param_value(self.params.index(name), reported_index=UINT16_MAX), True)]

    def _request_data_stream(self, msg, channel: int, t: float) -> None:
        """`GCS_MAVLINK::handle_request_data_stream`: start_stop 1 sets the rate (uint16 read as int16), 0 sets 0,
        anything else is ignored, as is every request on a link with MAVn_OPTIONS bit 2 (4.7); stream 0 sets every
        group but PARAMS, unknown streams nothing. Not saved
        (`persist_streamrates()` is false for Sub): a reboot brings back the stored rates."""
        if msg.start_stop not in (0, 1) or self.params.link_options(channel) & NO_STREAM_OVERRIDE:
            return
        groups = tuple(g for g in STREAM_GROUPS if g != "PARAMS") if msg.req_stream_id == 0 else \
            schedule.DATA_STREAM_GROUPS.get(msg.req_stream_id, ())
        rate = wrap(msg.req_message_rate, 16) if msg.start_stop else 0
        for group in groups:                   # in RAM only: Sub does not persist stream rates
            self.params.set(self.params.names.stream(channel, group), rate, save=False)
        self.on_params_changed(t)

    # -- MAVLink FTP -----------------------------------------------------------------------------------------

    def _ftp_refusal(self, msg):
        """ACK to session resets, NAK to everything else: no files here, so clients fall back to PARAM_*."""
        payload = bytes(msg.payload)
        seq, session, opcode = struct.unpack_from("<HBB", payload)
        if opcode in (FTP_TERMINATE, FTP_RESET):
            reply, size, data = FTP_ACK, 0, b""
        else:
            error = FTP_ERR_FILE_NOT_FOUND if opcode in (FTP_LIST, FTP_OPEN_RO) else FTP_ERR_UNKNOWN_COMMAND
            reply, size, data = FTP_NAK, 1, bytes([error])
        body = struct.pack("<HBBBBBBI", (seq + 1) & 0xFFFF, session, reply, size, opcode, 0, 0, 0) + data
        return ENCODER.file_transfer_protocol_encode(0, msg.get_srcSystem(), msg.get_srcComponent(),
                                                     list(body.ljust(251, b"\0")))


def _param_name(raw) -> str:
    if isinstance(raw, bytes):
        raw = raw.decode(errors="replace")
    return raw.split("\0", 1)[0]
