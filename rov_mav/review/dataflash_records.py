"""A DataFlash log (.BIN) read as records: each record type's fields as columns, by the labels of the file's own FMT
records, with the values pymavlink's DFReader gives them (its format characters: `c`/`C`/`e`/`E` hundredths, `L`
1e-7 degrees; text null-terminated). Nothing passes through another message's fields, so nothing is clamped.

pymavlink's indexer finds every record (the offsets of each type, resynchronising past damage as DFReader does);
the records of one type, all of one length, are then decoded at once through a numpy layout built from the type's
format string: a log is read at the speed of copying its bytes, and only the types asked for are held.
"""

from __future__ import annotations

import os
import re
import sys
import tempfile
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pymavlink import DFReader

from rov_mav.config import ConfigError
from rov_mav.review.tlog import ReadReport, regular_file

HEADER = 3                    # bytes before a record's fields: 0xA3 0x95 and the type id
_LAYOUT = {                   # DataFlash format character -> (numpy type, scale DFReader applies)
    "a": ("(32,)<i2", None), "b": ("i1", None), "B": ("u1", None), "h": ("<i2", None), "H": ("<u2", None),
    "i": ("<i4", None), "I": ("<u4", None), "f": ("<f4", None), "d": ("<f8", None), "g": ("<f2", None),
    "n": ("S4", None), "N": ("S16", None), "Z": ("S64", None), "M": ("i1", None), "q": ("<i8", None),
    "Q": ("<u8", None), "c": ("<i2", 100.0), "C": ("<u2", 100.0), "e": ("<i4", 100.0), "E": ("<u4", 100.0),
    "L": ("<i4", 1e7),
}
_SKIPPED = re.compile(r"Skipped (\d+) bad bytes in log at offset (\d+)")


@dataclass(frozen=True)
class Records:
    """The records of one type, in file order: `columns[label]` one value per record."""

    name: str
    columns: dict[str, np.ndarray]

    def __len__(self) -> int:
        return len(next(iter(self.columns.values()))) if self.columns else 0

    def __contains__(self, label: str) -> bool:
        return label in self.columns

    def __getitem__(self, label: str) -> np.ndarray:
        return self.columns[label]

    def get(self, label: str, default: float = np.nan) -> np.ndarray:
        """A column, or `default` for each record when this log's layout of the type lacks it."""
        return self.columns[label] if label in self.columns else np.full(len(self), default)

    def where(self, keep: np.ndarray) -> Records:
        """The records where `keep` is true."""
        return Records(self.name, {label: values[keep] for label, values in self.columns.items()})

    def texts(self, label: str) -> list[str]:
        """A text column as DFReader gives it: UTF-8 (else Latin-1), up to its first NUL."""
        return [_text(raw) for raw in self.columns[label]]


def _text(raw: bytes) -> str:
    raw = raw.split(b"\0", 1)[0]
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError:
        return raw.decode("ISO-8859-1")


@contextmanager
def reader_noise(report: ReadReport):
    """DFReader (its C indexer too) tells of damage on stderr: kept from the user's terminal, read for the report's
    damaged stretches."""
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as noise:
        os.dup2(noise.fileno(), 2)
        try:
            yield
        finally:
            sys.stderr.flush()
            os.dup2(saved, 2)
            os.close(saved)
            noise.seek(0)
            for size, offset in _SKIPPED.findall(noise.read().decode(errors="replace")):
                report.damaged.append((int(offset), int(offset) + int(size)))


def open_dataflash(path: str | Path, report: ReadReport) -> DFReader.DFReader_binary:
    """DFReader on a .BIN, indexed; ConfigError in one line when the file is none."""
    path = regular_file(path)
    report.size, report.dataflash = path.stat().st_size, True
    if report.size == 0:
        raise ConfigError(f"{path}: empty: not a dataflash log")
    with reader_noise(report):
        try:
            return DFReader.DFReader_binary(str(path), zero_time_base=True)
        except Exception as exc:     # noqa: BLE001 - pymavlink raises anything on a file it cannot index
            raise ConfigError(f"{path}: cannot read as a dataflash log: {exc}") from None


def read_records(path: str | Path, names: Iterable[str], report: ReadReport | None = None) -> dict[str, Records]:
    """The records of each type in `names` that the log holds (a type it lacks is left out)."""
    report = report if report is not None else ReadReport(str(path), 0)
    reader = open_dataflash(path, report)
    try:
        return dict(records_of(reader, names))
    finally:
        reader.filehandle.close()


def records_of(reader: DFReader.DFReader_binary, names: Iterable[str]) -> Iterator[tuple[str, Records]]:
    """(name, Records) from an open, indexed DFReader, for each type in `names` it holds."""
    data = np.frombuffer(reader.data_map, dtype=np.uint8)
    for name in names:
        type_id = reader.name_to_id.get(name)
        if type_id is None or not reader.offsets[type_id]:
            continue
        yield name, _decode(data, reader.formats[type_id], np.asarray(reader.offsets[type_id], dtype=np.int64))


def _decode(data: np.ndarray, fmt, offsets: np.ndarray) -> Records:
    """Every record of one type at once: their bytes gathered into rows, viewed through the type's layout."""
    layout = np.dtype([(f"f{i}", _LAYOUT[char][0]) for i, char in enumerate(fmt.format)])
    size = fmt.len - HEADER
    if layout.itemsize != size:
        raise ConfigError(f"DataFlash type {fmt.name}: its FMT says {fmt.len} bytes, its format "
                          f"{fmt.format!r} {layout.itemsize + HEADER}: not a layout this reader knows")
    offsets = offsets[offsets + fmt.len <= data.size]            # a record cut by the end of the file is none
    rows = np.lib.stride_tricks.sliding_window_view(data, size)[offsets + HEADER] if offsets.size else \
        np.zeros((0, size), dtype=np.uint8)
    fields = np.ascontiguousarray(rows).view(layout).reshape(-1)
    columns = {}
    for i, (label, char) in enumerate(zip(fmt.columns, fmt.format)):
        values = fields[f"f{i}"]
        scale = _LAYOUT[char][1]
        if scale is not None:
            values = values.astype(np.float64) / scale
        elif values.dtype.kind == "f":
            values = values.astype(np.float64)
        columns[label] = values
    return Records(fmt.name, columns)
