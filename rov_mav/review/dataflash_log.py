"""A vehicle's own DataFlash log (.BIN: ArduSub's on-board log, or the built-in vehicle's) read as the telemetry it
would have sent, so that `analyze` reviews it as it reviews a .tlog (`dive.DiveRecorder` takes the messages).

pymavlink's DFReader decodes every record through the file's own FMT records (layouts differ from ArduSub 4.0 to
4.7: ATT in centidegrees or float degrees, EKF2's NKF1 or EKF3's XKF1 with or without a core field, BAT with or
without RemPct); fields are looked up by label. Each record becomes the message the vehicle streams for it, stamped
with its TimeUS as both the log time and the vehicle's time_boot_ms (a DataFlash log has no wall clock without GPS):
    ATT + RATE -> ATTITUDE, XKF1 (core 0) / NKF1 -> LOCAL_POSITION_NED, RCOU -> SERVO_OUTPUT_RAW, RCIN -> RC_CHANNELS,
    BAT -> SYS_STATUS and BATTERY_STATUS, BARO of the Bar30 (instance 1) -> SCALED_PRESSURE2, CTUN's Alt (Sub's own
    altitude) -> GLOBAL_POSITION_INT's relative_alt (no latitude or longitude), RFND looking down
    with a good status -> RANGEFINDER, MODE + ARM (or EV's armed/disarmed) -> HEARTBEAT, MSG -> STATUSTEXT (a "GCS:" or
    "SRC=sysid/compid:" text as that station's, `GCS_MAVLINK::handle_statustext`), PARM -> PARAM_VALUE.
A damaged stretch is skipped (DFReader resynchronises on the next record header); a cut-off last record is dropped,
and the report says where the file stopped.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterator
from pathlib import Path

from rov_mav.flight.link import mavlink
from rov_mav.review.dataflash_records import open_dataflash, reader_noise
from rov_mav.review.tlog import ReadReport

VEHICLE = (1, 1)
GCS = (255, 190)
_SOURCE = re.compile(r"^SRC=(\d+)/(\d+):")
EV_ARMED, EV_DISARMED = 10, 11          # LogEvent ids (AP_Logger/LogStructure.h)
MAV_MODE_ARMED_MANUAL = 81              # custom | stabilize | manual input, as ArduSub's HEARTBEAT base_mode
_RC_LABELS = [[f"C{i}", f"Ch{i}", f"Chan{i}"] for i in range(1, 17)]
BAR30_INSTANCE = 1                      # ArduSub's second barometer: the Bar30 (SCALED_PRESSURE2 on the link)
DOWN = 25                               # MAV_SENSOR_ROTATION_PITCH_270: a rangefinder looking down
RANGEFINDER_GOOD = 4                    # RFND.Stat (`RangeFinder::Status`): 0 not connected, 1 no data, 2 out of range
                                        # low, 3 high, 4 good: only a good reading is a distance
STRETCH = 20000                         # records decoded at a time (a 100 MB log is millions)


def read_dataflash(path: str | Path, report: ReadReport | None = None) -> Iterator[tuple[float, object]]:
    """(log time s, MAVLink message) for the records of a .BIN, in order; `report` filled in as it goes."""
    report = report if report is not None else ReadReport(str(path), 0)
    reader = open_dataflash(path, report)
    encoders = {}
    with reader_noise(report):
        armed = _armed_at_start(reader)
    replay = _Replay(lambda source: encoders.setdefault(source, mavlink.MAVLink(None, *source)), armed)
    try:
        done = False
        while not done:
            with reader_noise(report):          # a stretch at a time: a large log is never held whole
                records, done = _read(reader, STRETCH, report)
            for record in records:
                report.messages += 1
                for t, msg in replay.take(record):
                    report.last_wall = t
                    yield t, msg
    finally:
        reader.filehandle.close()


def _read(reader, count: int, report: ReadReport) -> tuple[list, bool]:
    """Up to `count` records from `reader`, and whether the readable part has ended (its end, or a record that
    decodes to nonsense)."""
    records = []
    while len(records) < count:
        try:
            record = reader.recv_msg()
        except Exception:        # noqa: BLE001 - a record that decodes to nonsense ends the readable part
            return records, True
        if record is None:
            return records, True
        records.append(record)
        report.end = reader.offset
    return records, False


def _armed_at_start(reader) -> bool:
    """Was the vehicle armed when its log began? ArduSub opens a log at arming unless LOG_DISARMED is 1
    (`AP_Logger::should_log`), and the arming that opened it is not in it: a log starts armed when its first arming
    event (ARM, or EV 10/11 in older logs) is a disarm, or, with none, when it was written armed only (LOG_DISARMED
    0). Read ahead through DFReader's index of each record type, then rewound."""
    events = [(r.TimeUS, bool(r.ArmState)) for r in _first_records(reader, "ARM", 1)]
    events += [(r.TimeUS, r.Id == EV_ARMED) for r in _first_records(reader, "EV", None)
               if r.Id in (EV_ARMED, EV_DISARMED)][:1]
    written_disarmed = next((r.Value for r in _first_records(reader, "PARM", None) if r.Name == "LOG_DISARMED"), 0)
    reader.rewind()
    if events:
        return not min(events)[1]
    return not written_disarmed


def _first_records(reader, name: str, count: int | None) -> Iterator:
    """The first `count` (None: all) records of type `name`, read by DFReader's index (offsets per type)."""
    type_id = reader.name_to_id.get(name)
    if type_id is None:
        return
    for offset in reader.offsets[type_id][:count]:
        reader.offset = offset
        try:
            record = reader.recv_msg()
        except Exception:        # noqa: BLE001 - a record that decodes to nonsense is no event
            continue
        if record is not None and record.get_type() == name:
            yield record


class _Replay:
    """DataFlash records -> the messages ArduSub would have streamed (see the module)."""

    def __init__(self, encoder_of, armed: bool = False):
        self.encoder_of = encoder_of
        self.armed = armed
        self.mode = 0
        self.rates = (0.0, 0.0, 0.0)            # rad/s, from the last RATE

    def _packed(self, source: tuple[int, int], msg):
        msg.pack(self.encoder_of(source))
        return msg

    def take(self, r) -> list[tuple[float, object]]:
        kind = r.get_type()
        fields = r.get_fieldnames()
        if "TimeUS" not in fields:
            return []
        t = r.TimeUS * 1e-6
        ms = int(r.TimeUS // 1000) & 0xFFFFFFFF
        enc = self.encoder_of(VEHICLE)
        out = []
        if kind == "RATE":
            self.rates = tuple(math.radians(getattr(r, k, 0.0)) for k in ("R", "P", "Y"))
        elif kind == "ATT":
            roll, pitch, yaw = (math.radians(getattr(r, k)) for k in ("Roll", "Pitch", "Yaw"))
            yaw = math.remainder(yaw, 2 * math.pi)
            out.append(enc.attitude_encode(ms, roll, pitch, yaw, *self.rates))
        elif kind in ("XKF1", "NKF1") and getattr(r, "C", 0) == 0:
            out.append(enc.local_position_ned_encode(ms, r.PN, r.PE, r.PD, r.VN, r.VE, r.VD))
        elif kind == "RCOU":
            out.append(enc.servo_output_raw_encode(int(r.TimeUS) & 0xFFFFFFFF, 0, *_channels(r, 16)))
        elif kind == "RCIN":
            values = _channels(r, 18)
            out.append(enc.rc_channels_encode(ms, 16, *values, 255))
        elif kind in ("BAT", "CURR") and getattr(r, "Inst", getattr(r, "Instance", 0)) == 0:
            volt, curr = getattr(r, "Volt", math.nan), getattr(r, "Curr", math.nan)
            consumed = getattr(r, "CurrTot", math.nan)
            millivolts, centiamps = _fit(volt * 1000, UINT16, 65535), _fit(curr * 100, INT16, -1)
            out.append(enc.sys_status_encode(0, 0, 0, 0, millivolts, centiamps, -1, 0, 0, 0, 0, 0, 0))
            # BAT.RemPct 255 is ArduPilot's "unknown", as anything beyond 0-100: BATTERY_STATUS's -1
            out.append(enc.battery_status_encode(0, 0, 0, 32767, [millivolts] + [65535] * 9, centiamps,
                                                 _fit(consumed, INT32, -1), -1,
                                                 _fit(getattr(r, "RemPct", -1), (0, 100), -1)))
        elif kind == "BARO" and getattr(r, "I", 0) == BAR30_INSTANCE and "Press" in fields:
            out.append(enc.scaled_pressure2_encode(ms, r.Press / 100.0, 0.0, _fit(getattr(r, "Temp", 0) * 100, INT16, 0)))
        elif kind == "RFND" and getattr(r, "Orient", DOWN) == DOWN and "Dist" in fields \
                and getattr(r, "Stat", RANGEFINDER_GOOD) == RANGEFINDER_GOOD:
            out.append(enc.rangefinder_encode(float(r.Dist), 0.0))
        elif kind == "CTUN" and "Alt" in fields:          # Sub's altitude estimate (m, negative underwater)
            out.append(enc.global_position_int_encode(ms, 0, 0, 0, _fit(r.Alt * 1000, INT32, 0), 0, 0, 0, 65535))
        elif kind == "MODE":
            self.mode = int(getattr(r, "ModeNum", getattr(r, "Mode", 0)))
            out.append(self._heartbeat(enc))
        elif kind == "ARM":
            self.armed = bool(r.ArmState)
            out.append(self._heartbeat(enc))
        elif kind == "EV" and r.Id in (EV_ARMED, EV_DISARMED):
            self.armed = r.Id == EV_ARMED
            out.append(self._heartbeat(enc))
        elif kind == "MSG":
            text = str(r.Message)
            source, body = VEHICLE, text
            if text.startswith("GCS:"):
                source, body = GCS, text[4:]
            elif found := _SOURCE.match(text):
                source, body = (int(found.group(1)), int(found.group(2))), text[found.end():]
            msg = mavlink.MAVLink_statustext_message(mavlink.MAV_SEVERITY_INFO, body.encode()[:50])
            return [(t, self._packed(source, msg))]
        elif kind == "PARM":
            out.append(enc.param_value_encode(str(r.Name).encode(), float(r.Value), mavlink.MAV_PARAM_TYPE_REAL32,
                                              0, 65535))
        for msg in out:
            msg.pack(enc)
        return [(t, msg) for msg in out]

    def _heartbeat(self, enc):
        base = MAV_MODE_ARMED_MANUAL | (mavlink.MAV_MODE_FLAG_SAFETY_ARMED if self.armed else 0)
        return enc.heartbeat_encode(mavlink.MAV_TYPE_SUBMARINE, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, base, self.mode,
                                    mavlink.MAV_STATE_ACTIVE if self.armed else mavlink.MAV_STATE_STANDBY)


def _channels(r, count: int) -> list[int]:
    out = []
    for labels in _RC_LABELS[:min(count, 16)]:
        value = next((getattr(r, name) for name in labels if name in r.get_fieldnames()), 0)
        out.append(min(max(int(value), 0), 65535))
    return out + [0] * (count - len(out))


UINT16, INT16, INT32 = (0, 65534), (-32768, 32767), (-2**31, 2**31 - 1)   # the MAVLink fields' ranges (65535: unset)


def _fit(value: float, limits: tuple[int, int], missing: int) -> int:
    """`value` rounded for a MAVLink field whose values lie within `limits`; `missing` (the field's "unknown") when it
    is not a number or lies beyond them: never clamped to a value the vehicle did not log."""
    if not math.isfinite(value) or not limits[0] <= round(value) <= limits[1]:
        return missing
    return int(round(value))
