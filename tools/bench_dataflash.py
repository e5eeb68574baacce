"""How fast a long DataFlash log is read and reviewed, beside pymavlink's DFReader on the same file, in one run.

A long .BIN is made by repeating a real one (default: the pilot's dive mohai-2023-10-18-00000016.BIN of the real
logs, ROVMAV_REAL_LOGS) until it is --megabytes long. Each stage runs in a fresh process, which reports its wall
time and its peak memory (ru_maxrss):
  1. DFReader alone: every record decoded (`recv_msg`), as a reader of the file at all must;
  2. rov-mav's record reader (`review.dataflash_records.read_records`): every type's columns;
  3. `rov-mav analyze` end to end (figures and the Rerun recording to a temporary folder).

    .venv/bin/python tools/bench_dataflash.py [--log FILE.BIN] [--megabytes 100]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_LOG = "mohai-2023-10-18-00000016.BIN"

STAGE = textwrap.dedent("""
    import json, resource, sys, time
    stage, path, out = sys.argv[1:4]
    start = time.perf_counter()
    if stage == "dfreader":
        from pymavlink import DFReader
        reader = DFReader.DFReader_binary(path)
        n = 0
        while reader.recv_msg() is not None:
            n += 1
    elif stage == "records":
        from rov_mav.review.dataflash_records import index_dataflash
        from rov_mav.review.tlog import ReadReport
        index = index_dataflash(path, ReadReport(path, 0))
        n = sum(len(r) for _, r in index.records(index.name_to_id))
    else:
        from rov_mav import cli
        code = cli.main(["analyze", path, "--out", out, "--rerun", f"save:{out}/dive.rrd"])
        assert code == 0, code
        n = json.load(open(f"{out}/metrics.json"))["source"]["tlog"]["messages"]
    took = time.perf_counter() - start
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    print(json.dumps({"seconds": took, "peak_mb": peak, "records": n}))
""")


def long_log(source: Path, megabytes: float, folder: Path) -> Path:
    """`source` repeated until the file is `megabytes` long (each copy whole: its own FMT records again)."""
    data = source.read_bytes()
    copies = max(1, round(megabytes * 1e6 / len(data)))
    path = folder / f"{source.stem}-x{copies}.BIN"
    with path.open("wb") as f:
        for _ in range(copies):
            f.write(data)
    return path


def stage(name: str, path: Path, out: Path) -> dict:
    result = subprocess.run([sys.executable, "-c", STAGE, name, str(path), str(out)], capture_output=True, text=True,
                            cwd=ROOT)
    if result.returncode != 0:
        raise SystemExit(f"stage {name} failed:\n{result.stderr[-2000:]}")
    return json.loads(result.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--log", type=Path, help=f"a .BIN (default: {DEFAULT_LOG} in ROVMAV_REAL_LOGS)")
    parser.add_argument("--megabytes", type=float, default=100.0,
                        help="length of the long log (default 100; 0: the log as it is)")
    args = parser.parse_args()
    source = args.log or Path(os.environ.get("ROVMAV_REAL_LOGS", ROOT.parent / "shared" / "logs")) / DEFAULT_LOG
    if not source.is_file():
        raise SystemExit(f"{source}: no such .BIN (give --log, or set ROVMAV_REAL_LOGS)")
    with tempfile.TemporaryDirectory() as tmp:
        path = long_log(source, args.megabytes, Path(tmp))
        size = path.stat().st_size / 1e6
        print(f"{path.name}: {size:.1f} MB; load average {' '.join(f'{v:.2f}' for v in os.getloadavg())}, "
              f"{os.cpu_count()} cores")
        results = {}
        for name, label in (("dfreader", "DFReader alone (recv_msg)"), ("records", "rov-mav's record reader"),
                            ("analyze", "rov-mav analyze, end to end")):
            out = Path(tmp) / name
            out.mkdir()
            r = results[name] = stage(name, path, out)
            print(f"  {label:<30} {r['seconds']:7.2f} s  {size / r['seconds']:7.1f} MB/s  peak {r['peak_mb']:7.0f} MB"
                  f"  {r['records']:,} records")
        base = results["dfreader"]["seconds"]
        print(f"  speed against DFReader alone: records x{base / results['records']['seconds']:.1f}, analyze "
              f"x{base / results['analyze']['seconds']:.2f}")


if __name__ == "__main__":
    main()
