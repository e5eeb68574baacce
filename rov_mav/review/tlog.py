"""A telemetry log (.tlog, as rov-mav, MAVProxy and QGroundControl write it) read as far as it goes.

Each record is 8 bytes of big-endian microseconds since the epoch (the low 2 bits name the link), then one MAVLink
packet. pymavlink decodes it, drops packets whose CRC fails and resynchronises on the next packet; this reader
accounts for every byte around that: a record that does not start where the previous one ended marks a damaged
stretch (its own timestamp is read back from the 8 bytes before its packet), bytes after the last whole record
mark where the file stopped. A timestamp far from both its neighbours (a flipped bit) takes its predecessor's time.
"""

from __future__ import annotations

import stat
import struct
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

from rov_mav.config import ConfigError
from rov_mav.flight.session.link import mavutil

STAMP = 8                 # bytes of timestamp before each packet
TIME_JUMP = 60.0          # s: a record's wall time this far from both neighbours is a damaged timestamp
DATAFLASH_TEXT = ".log"   # the DataFlash text form (mavlogdump's, old ArduPilot's): not read
MAX_RECORD = 256          # bytes: a DataFlash record's largest size (its length field is one byte)


@dataclass
class ReadReport:
    """What was read of one file, and where it was damaged or stopped (byte offsets)."""

    path: str
    size: int
    messages: int = 0
    end: int = 0                                   # byte just past the last whole record
    damaged: list[tuple[int, int]] = field(default_factory=list)   # [start, end) stretches skipped
    fixed_times: int = 0                           # records whose timestamp was replaced
    last_wall: float | None = None                 # wall time (s since the epoch) of the last whole record
    dataflash: bool = False                        # a vehicle's on-board log (.BIN), not a telemetry log
    unchecked: dict[tuple[int, int, int], int] = field(default_factory=dict)   # (sysid, compid, msgid) -> whole
                                                   # packets whose CRC did not check: of another definition version

    @property
    def truncated(self) -> bool:
        return self.end < self.size

    @property
    def power_off_tail(self) -> bool:
        """A DataFlash log whose only flaw is an unfinished last record, shorter than any record can be: how a log
        ends when the vehicle's power goes (AP_Logger writes whole blocks as they fill), not damage."""
        return self.dataflash and self.truncated and not self.damaged and self.size - self.end < MAX_RECORD

    @property
    def complete(self) -> bool:
        """Read whole: nothing damaged, nothing cut but a power-off's unfinished last record."""
        return not ((self.truncated and not self.power_off_tail) or self.damaged or self.fixed_times)

    def describe(self) -> str:
        """One line: complete, or where it was damaged and where it stopped."""
        parts = [f"{self.path}: {self.messages} messages in {self.size} bytes"]
        if self.damaged:
            skipped = sum(b - a for a, b in self.damaged)
            where = ", ".join(f"{a}-{b}" for a, b in self.damaged[:3]) + (" ..." if len(self.damaged) > 3 else "")
            parts.append(f"{skipped} damaged bytes skipped in {len(self.damaged)} place(s) (bytes {where})")
        if self.fixed_times:
            parts.append(f"{self.fixed_times} damaged timestamp(s) replaced")
        if self.unchecked:
            parts.append(f"{sum(self.unchecked.values())} whole message(s) whose CRC did not check against "
                         "pymavlink's definitions, not read (another definition version: "
                         + ", ".join(f"{n} of msgid {m} from {s}/{c}" for (s, c, m), n in
                                     sorted(self.unchecked.items(), key=lambda kv: -kv[1])[:4])
                         + (" ..." if len(self.unchecked) > 4 else "") + ")")
        if self.power_off_tail:
            parts.append(f"STOPPED at byte {self.end}: the last {self.size - self.end} bytes are an unfinished record, "
                         "as a power-off leaves a log's end")
        elif self.truncated:
            parts.append(f"STOPPED at byte {self.end}: the last {self.size - self.end} bytes are not a whole record "
                         "(truncated or damaged end)")
        return "; ".join(parts) if len(parts) > 1 else parts[0] + ", complete"


def read_tlog(path: str | Path, report: ReadReport | None = None) -> Iterator[tuple[float, object]]:
    """(wall time s, message) for every whole record of the file, in order; `report` (if given) is filled in as it
    goes. ConfigError when the file cannot be opened or is a DataFlash text log (a .BIN goes to
    `dataflash_log.read_dataflash`)."""
    path = regular_file(path)
    if path.suffix.lower() == DATAFLASH_TEXT:
        raise ConfigError(f"{path}: a dataflash text log (.log); analyze reads telemetry logs (.tlog) and the "
                          "vehicle's binary dataflash logs (.BIN)")
    try:
        conn = mavutil.mavlink_connection(str(path), robust_parsing=True)
        raw = open(path, "rb")
    except OSError as exc:
        raise ConfigError(f"{path}: cannot open: {(exc.strerror or str(exc)).lower()}") from None
    report = report if report is not None else ReadReport(str(path), 0)
    report.size = path.stat().st_size
    window: list[list] = []            # up to three [wall, msg] records: the middle one is judged by its neighbours
    autopilots: set[tuple[int, int]] = set()        # (sysid, compid) of the ArduPilot autopilots heard
    passed_over: list[tuple[int, int, list]] = []   # whole packets pymavlink did not decode: (start, end, their keys)
    try:
        while True:
            msg = conn.recv_msg()
            if msg is None:
                break
            if msg.get_type() == "BAD_DATA":
                continue
            end = conn.f.tell()
            start = end - STAMP - len(msg.get_msgbuf())
            wall = msg._timestamp
            if msg.get_type() == "HEARTBEAT" and msg.autopilot == mavutil.mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA:
                autopilots.add((msg.get_srcSystem(), msg.get_srcComponent()))
            if start != report.end:
                if (packets := _whole_packets(raw, report.end, start)) is None:
                    report.damaged.append((report.end, start))
                else:
                    passed_over.append((report.end, start, packets))
                wall = _stamp_at(raw, start)
            report.end = end
            report.messages += 1
            window.append([wall, msg])
            if len(window) == 3:
                _judge(window, report)
                yield _done(window.pop(0), report)
        if len(window) == 2 and abs(window[1][0] - window[0][0]) > TIME_JUMP:    # the last record
            window[1][0] = window[0][0]
            report.fixed_times += 1
        for record in window:
            yield _done(record, report)
        _sort_passed_over(passed_over, autopilots, report)
    finally:
        conn.close()
        raw.close()


def regular_file(path: str | Path) -> Path:
    """`path` if it is a regular file; ConfigError otherwise (a FIFO or device is refused, never opened: reading
    it could wait forever)."""
    path = Path(path)
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        raise ConfigError(f"{path}: no such file or folder") from None
    except OSError as exc:
        raise ConfigError(f"{path}: cannot open: {(exc.strerror or str(exc)).lower()}") from None
    if not stat.S_ISREG(mode):
        raise ConfigError(f"{path}: not a regular file (a device, FIFO or socket)")
    return path


def _sort_passed_over(passed_over: list, autopilots: set, report: ReadReport) -> None:
    """Whole packets pymavlink passed over: from an ArduPilot autopilot of the log (its HEARTBEAT decoded: it speaks
    the definitions pymavlink has) the packet was damaged; from another component (a companion's service, a camera
    manager, built on another definition version) it is counted by source and id, not called damage."""
    for start, end, keys in passed_over:
        if any(key[:2] in autopilots for key in keys):
            report.damaged.append((start, end))
        else:
            for key in keys:
                report.unchecked[key] = report.unchecked.get(key, 0) + 1
    report.damaged.sort()


def _whole_packets(raw, start: int, end: int) -> list[tuple[int, int, int]] | None:
    """(sysid, compid, msgid) of each record in bytes [start, end) when they are whole timestamped MAVLink packets,
    framed as MAVLink 1 or 2 frames them, that pymavlink passed over (a CRC of another definition version: a
    companion's service, a camera manager); None when the bytes are not that (damage)."""
    raw.seek(start)
    data = raw.read(end - start)
    found, at = [], 0
    while at < len(data):
        head = data[at + STAMP:at + STAMP + 10]
        if len(head) < 6:
            return None
        if head[0] == 0xFD and len(head) == 10:           # MAVLink 2: len, incompat, compat, seq, sys, comp, id x3
            size = 12 + head[1] + (13 if head[2] & 1 else 0)
            key = (head[5], head[6], head[7] | head[8] << 8 | head[9] << 16)
        elif head[0] == 0xFE:                              # MAVLink 1: len, seq, sys, comp, id
            size = 8 + head[1]
            key = (head[3], head[4], head[5])
        else:
            return None
        at += STAMP + size
        found.append(key)
    return found if at == len(data) else None


def _stamp_at(raw, offset: int) -> float:
    raw.seek(offset)
    return struct.unpack(">Q", raw.read(STAMP))[0] * 1e-6


def _judge(window: list[list], report: ReadReport) -> None:
    """Three consecutive records: one whose time jumps away from two neighbours that agree takes the time of the
    one before it (the first record of a file, of the one after; the last, of the one before)."""
    (a, _), (b, _), (c, _) = window
    if abs(b - a) > TIME_JUMP and abs(c - a) <= TIME_JUMP:
        window[1][0] = a
        report.fixed_times += 1
    elif abs(a - b) > TIME_JUMP and abs(c - b) <= TIME_JUMP and report.last_wall is None:
        window[0][0] = b
        report.fixed_times += 1


def _done(record: list, report: ReadReport) -> tuple[float, object]:
    report.last_wall = record[0]
    return record[0], record[1]
