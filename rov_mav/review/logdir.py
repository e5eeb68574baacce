"""A run's `--log` folder read back: ticks.csv (what the controller saw and did, every tick), events.csv, run.json,
and the vehicle's side: mavlink.tlog, or the vehicle's own DataFlash log (.BIN) copied into the folder instead.

Each file is read as far as it goes: the first row that is not whole (a run killed while writing) ends it, and the
reader says at which line and byte. ticks.csv is streamed (an hour at 50 Hz is ~200 MB of text); a FIFO or device
in a file's place is refused, never opened.
"""

from __future__ import annotations

import csv
import io
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rov_mav import config
from rov_mav.config import ConfigError
from rov_mav.flight.record.runlog import RUN_INFO
from rov_mav.review.tlog import regular_file

TICKS, EVENTS, TLOG = "ticks.csv", "events.csv", "mavlink.tlog"
EVENTS_LIMIT = 64 << 20          # bytes: a run writes a few hundred lines of events
CHUNK = 10_000                   # tick rows converted to an array at a time


@dataclass
class RunFolder:
    ticks: dict[str, np.ndarray]     # column name -> (N,) floats; a column the log lacks is absent
    events: list[tuple[float, str, str]]   # (mission s, level, text)
    info: dict                       # run.json ({} when missing)
    tlog: Path | None                # mavlink.tlog, else the vehicle's .BIN copied in beside the run's files
    warnings: list[str]


def read_run_folder(path: Path) -> RunFolder:
    """ConfigError if `path` is not a run's log folder."""
    if not any((path / name).exists() for name in (TICKS, EVENTS, TLOG)):     # a .BIN alone is a .BIN's review
        raise ConfigError(f"{path}: not a run's log folder (no {TICKS}, {EVENTS} or {TLOG} in it)")
    warnings: list[str] = []
    ticks: dict[str, np.ndarray] = {}
    if (path / TICKS).exists():
        ticks, stopped = read_ticks(path / TICKS)
        rows = ticks["t"].size if "t" in ticks else 0
        if stopped:
            warnings.append(f"{path / TICKS}: read {rows} ticks, STOPPED at {stopped}")
    events: list[tuple[float, str, str]] = []
    if (path / EVENTS).exists():
        events, stopped = read_events(path / EVENTS)
        if stopped:
            warnings.append(f"{path / EVENTS}: read {len(events)} events, STOPPED at {stopped}")
    info: dict = {}
    if (path / RUN_INFO).exists():
        try:
            info = json.loads(config.read_text(path / RUN_INFO, kind="JSON"))
        except (ConfigError, ValueError) as exc:
            warnings.append(f"{path / RUN_INFO}: unreadable ({exc}); the mission's name and controller are unknown")
    tlog = path / TLOG if (path / TLOG).exists() else _vehicle_log(path, warnings)
    return RunFolder(ticks, events, info if isinstance(info, dict) else {}, tlog, warnings)


def _vehicle_log(path: Path, warnings: list[str]) -> Path | None:
    """Without mavlink.tlog, the vehicle's own DataFlash log copied into the folder (one .BIN) stands for it."""
    logs = sorted(p for p in path.iterdir() if p.suffix.lower() == ".bin")
    if len(logs) > 1:
        warnings.append(f"{path}: {len(logs)} .BIN files and no {TLOG}: none used (keep the one of this run)")
    return logs[0] if len(logs) == 1 else None


def read_ticks(path: Path) -> tuple[dict[str, np.ndarray], str | None]:
    """ticks.csv's columns, and where it stopped ("line N (byte B): why") if not at its end. A whole, well-formed
    file is parsed at once by numpy; anything else row by row, to say where it stopped."""
    with open(regular_file(path), "rb") as f:
        first = f.readline()
        body = f.read()
    header_columns = first.decode("utf-8", errors="replace").strip().split(",")
    if "t" not in header_columns:
        return {}, "line 1 (byte 0): no 't' column: not a run's ticks file"
    width = len(header_columns)
    values = _whole(body, width)
    stopped = None
    if values is None:
        values, stopped = _row_by_row(body, width, len(first))
    return {name: values[:, i] for i, name in enumerate(header_columns)}, stopped


def _whole(body: bytes, width: int) -> np.ndarray | None:
    """(rows, width) of a body whose every row is whole and numeric, else None."""
    if not body:
        return np.empty((0, width))
    if not body.endswith(b"\n"):
        return None
    try:
        values = np.loadtxt(io.BytesIO(body), delimiter=",", comments=None, ndmin=2, dtype=float)
    except ValueError:
        return None
    rows = body.count(b"\n")
    if values.shape != (rows, width) and not (rows == 0 and values.size == 0):
        return None                            # a blank line (numpy skips it) or a row of another width
    return values.reshape(rows, width)


def _row_by_row(body: bytes, width: int, offset: int) -> tuple[np.ndarray, str | None]:
    """The rows up to the first that is cut short, of another width or not numeric, and where that one is."""
    chunks: list[np.ndarray] = []
    rows: list[list[float]] = []
    stopped = None
    for line, raw in enumerate(io.BytesIO(body), start=2):
        why = _invalid(raw, width)
        if why is not None:
            stopped = f"line {line} (byte {offset}): {why}"
            break
        rows.append([float(v) for v in raw.split(b",")])
        offset += len(raw)
        if len(rows) == CHUNK:
            chunks.append(np.array(rows))
            rows = []
    chunks.append(np.array(rows, dtype=float).reshape(len(rows), width))
    return np.concatenate(chunks), stopped


def column_block(ticks: dict[str, np.ndarray], names) -> np.ndarray:
    """(N, len(names)) of ticks.csv's columns `names` (a group of `flight.record.runlog`'s), NaN for a column the log
    lacks."""
    n = ticks["t"].size
    return np.stack([ticks.get(name, np.full(n, np.nan)) for name in names], axis=1)


def _invalid(raw: bytes, width: int) -> str | None:
    if not raw.endswith(b"\n"):
        return "the last row is cut short (no end of line)"
    fields = raw.split(b",")
    if len(fields) != width:
        return f"{len(fields)} fields, expected {width}"
    try:
        for value in fields:
            float(value)
    except ValueError:
        return f"'{value.strip().decode('utf-8', errors='replace')[:20]}' is not a number"
    return None


def read_events(path: Path) -> tuple[list[tuple[float, str, str]], str | None]:
    """events.csv's (t, level, text) rows, and where it stopped if not at its end."""
    text = config.read_bytes(path, EVENTS_LIMIT).decode("utf-8", errors="replace")
    reader = csv.reader(io.StringIO(text, newline=""))
    events: list[tuple[float, str, str]] = []
    try:
        next(reader, None)                                   # the header
        for row in reader:
            if len(row) != 3:
                return events, f"line {reader.line_num}: {len(row)} fields, expected 3"
            try:
                events.append((float(row[0]), row[1], row[2]))
            except ValueError:
                return events, f"line {reader.line_num}: '{row[0][:20]}' is not a time"
    except csv.Error as exc:
        return events, f"line {reader.line_num}: {exc}"
    if events and not text.endswith(("\n", "\r")):
        events.pop()
        return events, f"line {reader.line_num}: the last row is cut short (no end of line)"
    return events, None
