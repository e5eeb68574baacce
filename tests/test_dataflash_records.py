"""The DataFlash record reader held to pymavlink's DFReader, record for record and field for field, on every real
log of the corpus (ROVMAV_REAL_LOGS); where the records lie accounts for every byte."""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pytest
from pymavlink import DFReader

from rov_mav.review import dataflash_records
from rov_mav.review.dataflash_records import read_records
from rov_mav.review.tlog import ReadReport

FOLDER = os.environ.get("ROVMAV_REAL_LOGS")
REAL = sorted(p for p in Path(FOLDER).iterdir() if p.suffix == ".BIN") if FOLDER and Path(FOLDER).is_dir() else []


def _dfreader_columns(path: Path) -> dict[str, dict[str, list]]:
    """Every record of every type as DFReader decodes it, by type and label."""
    reader = DFReader.DFReader_binary(str(path))
    out: dict[str, dict[str, list]] = {}
    while (r := reader.recv_msg()) is not None:
        columns = out.setdefault(r.get_type(), {})
        for label in r.get_fieldnames():
            columns.setdefault(label, []).append(getattr(r, label))
    return out


def _same(mine, theirs) -> bool:
    if isinstance(theirs, float) and math.isnan(theirs):
        return isinstance(mine, float | np.floating) and math.isnan(mine)
    if isinstance(theirs, str):
        return mine == theirs
    if isinstance(theirs, bytes):           # FILE.Data: DFReader gives the raw bytes
        return mine == theirs.rstrip(b"\0")
    if hasattr(theirs, "tolist"):           # an 'a' array
        return list(mine) == list(theirs)
    return mine == theirs


@pytest.mark.skipif(not REAL, reason="ROVMAV_REAL_LOGS does not name a folder of real logs (.ci/run points it at the "
                                     "logs beside the checkout)")
@pytest.mark.parametrize("path", REAL, ids=[p.name for p in REAL])
def test_every_field_of_every_record_is_dfreaders(path):
    truth = _dfreader_columns(path)
    mine = read_records(path, truth)
    assert set(mine) == set(truth) - {"FMT"} | ({"FMT"} & set(mine))
    for name, columns in truth.items():
        if name == "FMT":
            continue
        records = mine[name]
        for label, values in columns.items():
            text = records[label].dtype.kind == "S" and not (name == "FILE" and label == "Data")
            got = records.texts(label) if text else records[label].tolist()
            assert len(got) == len(values), (name, label)
            bad = [i for i, (a, b) in enumerate(zip(got, values)) if not _same(a, b)]
            assert not bad, (name, label, bad[:3], [got[i] for i in bad[:3]], [values[i] for i in bad[:3]])


@pytest.mark.skipif(not REAL, reason="ROVMAV_REAL_LOGS does not name a folder of real logs")
def test_a_log_twice_over_is_twice_the_records_with_the_power_off_tail_between_as_damage(tmp_path):
    # the pilot's dive ends in an unfinished record (its power went): written twice in a row, the first copy's tail
    # runs into the second copy's first FMT record (89 bytes), which is lost: one damaged stretch at the junction,
    # found by where the records lie; the second copy's tail is where the file stops
    source = next(p for p in REAL if p.name == "mohai-2023-10-18-00000016.BIN")
    once, twice = ReadReport(str(source), 0), ReadReport("twice", 0)
    read_records(source, [], once)
    (tmp_path / "twice.BIN").write_bytes(source.read_bytes() * 2)
    read_records(tmp_path / "twice.BIN", [], twice)
    assert once.power_off_tail and not once.damaged
    assert 2 * once.messages - 2 <= twice.messages <= 2 * once.messages
    [(start, end)] = twice.damaged
    assert once.end <= start < end <= once.size + 2 * 89 and twice.end == once.size + once.end


@pytest.mark.skipif(not REAL, reason="ROVMAV_REAL_LOGS does not name a folder of real logs")
def test_without_pymavlinks_c_indexer_dfreaders_own_index_gives_the_same(monkeypatch):
    path = next(p for p in REAL if p.name == "beckett-2023-05-17-old5.BIN")
    fast = read_records(path, ["ATT", "CTUN", "MSG"])
    monkeypatch.setattr(dataflash_records.dfindexer, "available", False)
    slow = read_records(path, ["ATT", "CTUN", "MSG"])
    for name in fast:
        assert np.array_equal(fast[name].offsets, slow[name].offsets)
        assert all(np.array_equal(fast[name][label], slow[name][label]) for label in fast[name].columns)
