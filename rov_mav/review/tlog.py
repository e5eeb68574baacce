"""A telemetry log (.tlog, as rov-mav, MAVProxy and QGroundControl write it) read as far as it goes.

Each record is 8 bytes of big-endian microseconds since the epoch (the low 2 bits name the link), then one MAVLink
packet. pymavlink decodes it, drops packets whose CRC fails and resynchronises on the next packet; this reader
accounts for every byte around that: a record that does not start where the previous one ended marks a damaged
stretch (its own timestamp is read back from the 8 bytes before its packet), bytes after the last whole record
mark where the file stopped. A timestamp far from both its neighbours (a flipped bit) takes its predecessor's time.
"""

from __future__ import annotations

import struct
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

from rov_mav.config import ConfigError
from rov_mav.flight.link import mavutil

STAMP = 8                 # bytes of timestamp before each packet
TIME_JUMP = 60.0          # s: a record's wall time this far from both neighbours is a damaged timestamp
DATAFLASH = (".bin", ".log")


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

    @property
    def truncated(self) -> bool:
        return self.end < self.size

    def describe(self) -> str:
        """One line: complete, or where it was damaged and where it stopped."""
        parts = [f"{self.path}: {self.messages} messages in {self.size} bytes"]
        if self.damaged:
            skipped = sum(b - a for a, b in self.damaged)
            where = ", ".join(f"{a}-{b}" for a, b in self.damaged[:3]) + (" ..." if len(self.damaged) > 3 else "")
            parts.append(f"{skipped} damaged bytes skipped in {len(self.damaged)} place(s) (bytes {where})")
        if self.fixed_times:
            parts.append(f"{self.fixed_times} damaged timestamp(s) replaced")
        if self.truncated:
            parts.append(f"STOPPED at byte {self.end}: the last {self.size - self.end} bytes are not a whole record "
                         "(truncated or damaged end)")
        return "; ".join(parts) if len(parts) > 1 else parts[0] + ", complete"


def read_tlog(path: str | Path, report: ReadReport | None = None) -> Iterator[tuple[float, object]]:
    """(wall time s, message) for every whole record of the file, in order; `report` (if given) is filled in as it
    goes. ConfigError when the file cannot be opened or is a dataflash log."""
    path = Path(path)
    if path.suffix.lower() in DATAFLASH:
        raise ConfigError(f"{path}: a dataflash log (the vehicle's .bin); analyze reads telemetry logs (.tlog)")
    try:
        conn = mavutil.mavlink_connection(str(path), robust_parsing=True)
        raw = open(path, "rb")
    except OSError as exc:
        raise ConfigError(f"{path}: {exc.strerror or exc}") from None
    report = report if report is not None else ReadReport(str(path), 0)
    report.size = path.stat().st_size
    held: tuple[float, object] | None = None       # one record of lookahead, to judge its timestamp
    before: float | None = None                    # wall time of the record before `held`
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
            if start != report.end:
                report.damaged.append((report.end, start))
                wall = _stamp_at(raw, start)
            report.end = end
            report.messages += 1
            if held is not None:
                before = _judged(held, before, wall, report)
                yield before, held[1]
            held = (wall, msg)
        if held is not None:
            yield _judged(held, before, None, report), held[1]
    finally:
        conn.close()
        raw.close()


def _stamp_at(raw, offset: int) -> float:
    raw.seek(offset)
    return struct.unpack(">Q", raw.read(STAMP))[0] * 1e-6


def _judged(held: tuple[float, object], before: float | None, after: float | None, report: ReadReport) -> float:
    """The held record's wall time, replaced by its predecessor's when it jumps away from both neighbours."""
    wall = held[0]
    if before is not None and abs(wall - before) > TIME_JUMP and (after is None or abs(after - before) <= TIME_JUMP):
        report.fixed_times += 1
        wall = before
    report.last_wall = wall
    return wall
