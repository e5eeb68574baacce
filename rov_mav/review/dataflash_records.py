"""A DataFlash log (.BIN) read as records: each record type's fields as columns, by the labels of the file's own FMT
records, with the values pymavlink's DFReader gives them (its format characters: `c`/`C`/`e`/`E` hundredths, `L`
1e-7 degrees; text null-terminated). Nothing passes through another message's fields, so nothing is clamped.

pymavlink's own C indexer (the one DFReader uses) finds every record: the offsets of each type, resynchronising past
damage. The FMT records give each type's layout (pymavlink's `DFFormat`); the records of one type, all of one
length, are then decoded at once through a numpy layout built from its format string, so a log is read at the speed
of copying its bytes and only the types asked for are held. (DFReader itself, before the first record, reads the
whole log once through Python looking for a GPS clock: 20 s for 100 MB.) Whatever lies between one record's end
and the next record is a damaged stretch; bytes after the last whole record, where the file stopped.
"""

from __future__ import annotations

import mmap
import os
import sys
import tempfile
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pymavlink import DFReader, dfindexer

from rov_mav.config import ConfigError
from rov_mav.review.tlog import ReadReport, regular_file

HEADER = 3                    # bytes before a record's fields: 0xA3 0x95 and the type id
HEAD1, HEAD2 = 0xA3, 0x95
FMT_TYPE, FMT_LENGTH = 0x80, 89    # the FMT record's own type and length (AP_Logger/LogStructure.h)
_LAYOUT = {                   # DataFlash format character -> (numpy type, scale DFReader applies)
    "a": ("(32,)<i2", None), "b": ("i1", None), "B": ("u1", None), "h": ("<i2", None), "H": ("<u2", None),
    "i": ("<i4", None), "I": ("<u4", None), "f": ("<f4", None), "d": ("<f8", None), "g": ("<f2", None),
    "n": ("S4", None), "N": ("S16", None), "Z": ("S64", None), "M": ("i1", None), "q": ("<i8", None),
    "Q": ("<u8", None), "c": ("<i2", 100.0), "C": ("<u2", 100.0), "e": ("<i4", 100.0), "E": ("<u4", 100.0),
    "L": ("<i4", 1e7),
}


@dataclass(frozen=True)
class Records:
    """The records of one type, in file order: `columns[label]` one value per record."""

    name: str
    columns: dict[str, np.ndarray]
    offsets: np.ndarray                 # each record's byte offset in the file (file order is time order)

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
        return Records(self.name, {label: values[keep] for label, values in self.columns.items()}, self.offsets[keep])

    def texts(self, label: str) -> list[str]:
        """A text column as DFReader gives it: UTF-8 (else Latin-1), up to its first NUL."""
        return [_text(raw) for raw in self.columns[label]]


def first_core(records: Records | None) -> Records | None:
    """An EKF's records of its first core (core field C 0; a layout without the field has one core), None for none."""
    if records is None or not len(records):
        return None
    return records.where(records["C"] == 0) if "C" in records else records


def _text(raw: bytes) -> str:
    raw = raw.split(b"\0", 1)[0]
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError:
        return raw.decode("ISO-8859-1")


@contextmanager
def _quiet():
    """pymavlink's indexer prints a line for every damaged byte on stderr: kept from the user's terminal (the damage
    is accounted from where the records lie)."""
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


@dataclass
class DataflashIndex:
    """Where every record of a .BIN lies: `offsets[type id]` (numpy, file order), the types' `formats` (pymavlink's
    DFFormat, by id) and `name_to_id`; `data` the file's bytes (memory-mapped)."""

    data: np.ndarray
    formats: dict
    name_to_id: dict[str, int]
    offsets: dict[int, np.ndarray]

    def records(self, names: Iterable[str]) -> Iterator[tuple[str, Records]]:
        """(name, Records) for each type in `names` the log holds."""
        for name in names:
            type_id = self.name_to_id.get(name)
            if type_id is not None and self.offsets.get(type_id) is not None and self.offsets[type_id].size:
                decoded = _decode(self.data, self.formats[type_id], self.offsets[type_id])
                if decoded is not None:
                    yield name, decoded


def index_dataflash(path: str | Path, report: ReadReport) -> DataflashIndex:
    """Index a .BIN and fill `report` (size, records, damaged stretches, where it stopped); ConfigError in one line
    when the file is none."""
    path = regular_file(path)
    report.size, report.dataflash = path.stat().st_size, True
    if report.size == 0:
        raise ConfigError(f"{path}: empty: not a dataflash log")
    with path.open("rb") as f:
        mapped = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ)
    data = np.frombuffer(mapped, dtype=np.uint8)
    with _quiet():
        found = _offsets(path, mapped)
    fmt_format = DFReader.DFFormat(FMT_TYPE, "FMT", FMT_LENGTH, "BBnNZ", "Type,Length,Name,Format,Columns")
    formats, names = {FMT_TYPE: fmt_format}, {"FMT": FMT_TYPE}
    for offset in found.get(FMT_TYPE, ()):
        fields = _decode(data, fmt_format, np.array([offset], dtype=np.int64))
        if fields is None or not len(fields):
            continue
        type_id, length = int(fields["Type"][0]), int(fields["Length"][0])
        name, form, labels = (fields.texts(label)[0] for label in ("Name", "Format", "Columns"))
        try:
            formats[type_id] = DFReader.DFFormat(type_id, name, length, form, labels)
        except Exception:       # noqa: BLE001 - a format character pymavlink does not know: the type stays unread
            continue
        names[formats[type_id].name] = type_id
    offsets = {t: o for t, o in found.items() if t in formats}
    _account(report, offsets, formats, data.size)
    if not report.messages:
        raise ConfigError(f"{path}: no DataFlash record in its {report.size} bytes: not a dataflash log")
    return DataflashIndex(data, formats, names, offsets)


def _offsets(path: Path, mapped: mmap.mmap) -> dict[int, np.ndarray]:
    """pymavlink's C indexer's offsets of each record type (ids with none left out); without it, DFReader's own
    index (the same records, read slower)."""
    if dfindexer.available:
        found = dfindexer.build_offsets(memoryview(mapped), FMT_TYPE, FMT_LENGTH, 3, 4, HEAD1, HEAD2,
                                        progress_callback=None)
    else:
        try:
            found = DFReader.DFReader_binary(str(path)).offsets
        except Exception as exc:     # noqa: BLE001 - pymavlink raises anything on a file it cannot index
            raise ConfigError(f"{path}: cannot read as a dataflash log: {exc}") from None
    out = {}
    for t in range(len(found)):                  # each type's list of Python ints made an array and let go at once
        if len(found[t]):
            out[t] = np.asarray(found[t], dtype=np.int64)
        found[t] = None
    return out


def _account(report: ReadReport, offsets: dict[int, np.ndarray], formats: dict, size: int) -> None:
    """Records, damaged stretches (bytes between one record's end and the next record) and the end of the last
    whole record, from where the records lie. Records do not overlap, so their starts and their ends sorted apart
    pair up (the k-th start with the k-th end) without sorting the records themselves."""
    starts = np.sort(np.concatenate([o for o in offsets.values()] or [np.zeros(0, dtype=np.int64)]))
    ends = np.sort(np.concatenate([o + formats[t].len for t, o in offsets.items()] or [np.zeros(0, dtype=np.int64)]))
    whole = int(np.searchsorted(ends, size, side="right"))           # a record cut by the end of the file is none
    starts, ends = starts[:whole], ends[:whole]
    report.messages = int(starts.size)
    report.end = int(ends[-1]) if ends.size else 0
    previous = np.concatenate([[0], ends[:-1]])
    gaps = np.flatnonzero(starts > previous)
    report.damaged = [(int(previous[i]), int(starts[i])) for i in gaps]


def read_records(path: str | Path, names: Iterable[str], report: ReadReport | None = None) -> dict[str, Records]:
    """The records of each type in `names` that the log holds (a type it lacks is left out)."""
    report = report if report is not None else ReadReport(str(path), 0)
    return dict(index_dataflash(path, report).records(names))


def _decode(data: np.ndarray, fmt, offsets: np.ndarray) -> Records | None:
    """Every record of one type at once: their bytes gathered into rows, viewed through the type's layout; None when
    the FMT's length and its format disagree (DFReader cannot unpack such a type either)."""
    layout = np.dtype([(f"f{i}", _LAYOUT[char][0]) for i, char in enumerate(fmt.format)])
    size = fmt.len - HEADER
    if layout.itemsize != size:
        return None
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
    return Records(fmt.name, columns, offsets)
