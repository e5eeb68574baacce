"""How long `rov-mav analyze` takes, stage by stage, on the logs given: reading and decoding (messages per second),
measuring, the figures, the Rerun recording (to a temporary file).

    python tools/bench_analyze.py out/square/log flight.tlog [--mission missions/square.yaml]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from rov_mav.mission.missions import load_mission
from rov_mav.model.vehicle import load_vehicle
from rov_mav.review.dive_review import review_dive
from rov_mav.review.outputs import record, write_figures
from rov_mav.telemetry import default_blueprint, finish, open_recording, parse_target


def bench(path: Path, mission) -> None:
    start = time.perf_counter()
    review = review_dive(path, mission)
    reviewed = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        write_figures(review, Path(tmp))
        drawn = time.perf_counter()
        rec = open_recording(parse_target(f"save:{tmp}/dive.rrd"), default_blueprint(review.reference_path))
        record(review, rec, load_vehicle())
        finish(rec)
        recorded = time.perf_counter()
    tlog = review.metrics["source"].get("tlog") or {}
    states = 0 if review.trace is None else review.trace.t.size
    rate = f", {tlog['messages'] / (reviewed - start):,.0f} messages/s" if tlog else ""
    print(f"{path}: {tlog.get('messages', 0):,} messages ({tlog.get('bytes', 0) / 1e6:.1f} MB), {states:,} states")
    print(f"  read, decode and measure {reviewed - start:.2f} s{rate}; figures {drawn - reviewed:.2f} s; "
          f"recording {recorded - drawn:.2f} s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("paths", nargs="+", type=Path, help="run log folders or .tlog files")
    parser.add_argument("--mission", help="mission YAML to measure against")
    args = parser.parse_args()
    mission = load_mission(args.mission) if args.mission else None
    for path in args.paths:
        bench(path, mission)


if __name__ == "__main__":
    main()
