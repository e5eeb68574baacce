"""A run's `--log` folder read back: ticks.csv (what the controller saw and did, every tick), events.csv, run.json.

Each CSV is read as far as it goes: the first row that is not whole (a run killed while writing) ends it, and the
reader says at which line and byte.
"""

from __future__ import annotations

import csv
import io
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rov_mav.config import ConfigError
from rov_mav.flight.runlog import RUN_INFO

TICKS, EVENTS, TLOG = "ticks.csv", "events.csv", "mavlink.tlog"


@dataclass
class CsvRead:
    """A CSV read as far as it goes: rows, and where it stopped if it did not reach the end."""

    path: Path
    header: list[str]
    rows: list[list[str]]
    stopped: str | None = None       # "line N (byte B): why"


@dataclass
class RunFolder:
    ticks: dict[str, np.ndarray]     # column name -> (N,) floats; a column the log lacks is absent
    events: list[tuple[float, str, str]]   # (mission s, level, text)
    info: dict                       # run.json ({} when missing)
    tlog: Path | None
    warnings: list[str]


def is_run_folder(path: Path) -> bool:
    return path.is_dir() and any((path / name).exists() for name in (TICKS, EVENTS, TLOG))


def read_run_folder(path: Path) -> RunFolder:
    """ConfigError if `path` is not a run's log folder."""
    if not is_run_folder(path):
        raise ConfigError(f"{path}: not a run's log folder (no {TICKS}, {EVENTS} or {TLOG} in it)")
    warnings: list[str] = []
    ticks: dict[str, np.ndarray] = {}
    if (path / TICKS).exists():
        read = _read_csv(path / TICKS, float_columns=True)
        if read.stopped:
            warnings.append(f"{read.path}: read {len(read.rows)} ticks, STOPPED at {read.stopped}")
        values = np.array(read.rows, dtype=float).reshape(len(read.rows), len(read.header))
        ticks = {name: values[:, i] for i, name in enumerate(read.header)}
    events: list[tuple[float, str, str]] = []
    if (path / EVENTS).exists():
        read = _read_csv(path / EVENTS, float_columns=False)
        if read.stopped:
            warnings.append(f"{read.path}: read {len(read.rows)} events, STOPPED at {read.stopped}")
        events = [(float(t), level, text) for t, level, text in read.rows]
    info: dict = {}
    if (path / RUN_INFO).exists():
        try:
            info = json.loads((path / RUN_INFO).read_text())
        except (OSError, ValueError) as exc:
            warnings.append(f"{path / RUN_INFO}: unreadable ({exc}); the mission's name and controller are unknown")
    tlog = path / TLOG if (path / TLOG).exists() else None
    return RunFolder(ticks, events, info if isinstance(info, dict) else {}, tlog, warnings)


def _read_csv(path: Path, float_columns: bool) -> CsvRead:
    """Rows with as many fields as the header (all numbers when `float_columns`; else a number first), until the
    first that is not."""
    try:
        text = path.read_bytes().decode("utf-8", errors="replace")
    except OSError as exc:
        raise ConfigError(f"{path}: {exc.strerror or exc}") from None
    lines = text.splitlines(keepends=True)
    if not lines:
        return CsvRead(path, [], [], "line 1 (byte 0): empty file")
    starts = np.cumsum([0] + [len(line.encode()) for line in lines])     # byte offset of each line
    header = next(csv.reader([lines[0]]))
    rows: list[list[str]] = []
    reader = csv.reader(io.StringIO("".join(lines[1:])))
    consumed = 0                                                         # data lines read so far
    while True:
        where = f"line {consumed + 2} (byte {starts[consumed + 1]})"
        try:
            row = next(reader)
        except StopIteration:
            return CsvRead(path, header, rows)
        except csv.Error as exc:
            return CsvRead(path, header, rows, f"{where}: {exc}")
        consumed = reader.line_num
        whole = consumed < len(lines) - 1 or text.endswith(("\n", "\r"))
        why = _invalid(row, len(header), float_columns, whole)
        if why:
            return CsvRead(path, header, rows, f"{where}: {why}")
        rows.append(row)


def _invalid(row: list[str], width: int, float_columns: bool, complete: bool) -> str | None:
    if not complete:
        return "the last row is cut short (no end of line)"
    if len(row) != width:
        return f"{len(row)} fields, expected {width}"
    try:
        for value in (row if float_columns else row[:1]):
            float(value)
    except ValueError:
        return f"'{value}' is not a number"
    return None
