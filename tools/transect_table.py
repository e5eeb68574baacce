"""Measure: seafloor transects on the built-in vehicle, the controllers side by side on one bottom, current, sounder
and navigation.

For every bottom (flat, a 10 % slope, a rough 5 % slope, the bottom of a real dive: `tools/seafloor_from_log.py`'s
profile of the real SURFTRAK dive; and ice: the under-ice survey's ceiling, flown STANDOFF m below it with the
sounder looking up) x current across the line (none, 0.2 m/s) x echo sounder (ideal, ping) x navigation (dvl,
dvl+ugps) x controller (fuzzy and ismc holding the height with `rov_mav.mission.terrain`; ardusub-guided: ArduSub's
GUIDED holding it from its own rangefinder, as PR #27767 does; surftrak: ArduSub's SURFTRAK holding it, the speed and
the line a pilot's sticks, `tools/surftrak_pilot.py`; under the ice only fuzzy and ismc) x seed (the bridge's
`--seed`), it writes a transect mission (a hold, then LENGTH m north at 0.2 m/s, ALTITUDE m above the bottom), flies
it against a `rov-mav sim-bridge` process on its own link (`rov-mav run --target`, or the pilot), with a checker
station on a second link recording SERVO_OUTPUT_RAW for the thrusters' activity, and prints a markdown table of the
means over the seeds: the height error RMS against the true bottom (SimHeight) and its max, against the sounder, the
cross-track RMS of the estimate flown on and of the truth, the speed along the line off the plan, strikes under
0.3 m, activity, runs completed and end states. Run:
    .venv/bin/python tools/transect_table.py [--bottoms flat,slope,rough,real,ice] [--currents 0,0.2]
        [--sounders ideal,ping] [--navigation dvl,dvl+ugps] [--controllers fuzzy,ismc,ardusub-guided,surftrak]
        [--seeds 1,2] [--length 20] [--speedup 5] [--figure docs/results/figures/transects.png]
"""

from __future__ import annotations

import argparse
import itertools
import math
import os
import signal
import sys
import tempfile
from pathlib import Path

import numpy as np
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))
from link_faults import free_port, stop  # noqa: E402
from navigation_table import OutputRecorder, _stop_reason, fly_with_checker, start_bridge  # noqa: E402
from surftrak_pilot import fly_surftrak  # noqa: E402
from transect_figure import draw, read_rows  # noqa: E402
from vehicle_faults import mission_start  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from rov_mav.model.seafloor import parse_surface  # noqa: E402
from rov_mav.review.analysis import bottom_profile  # noqa: E402
from rov_mav.review.dive_review import read_dive  # noqa: E402

ALTITUDE = 1.0                   # m above the bottom
SPEED = 0.2                      # m/s along the line
REAL_LOG = "mohai-2023-10-18-09-55-06-surftrak.tlog"
BOTTOMS = {"flat": {"depth": 10.0}, "slope": {"depth": 10.0, "slope": 0.1},
           "rough": {"depth": 10.0, "slope": 0.05, "relief": 0.1, "wavelength": 3.0, "seed": 1},
           "ice": {"depth": 2.0, "relief": 0.15, "wavelength": 4.0, "seed": 2}}    # the under-ice survey's ceiling
STANDOFF = 1.5                   # m below the ice
BELOW_ICE = {"fuzzy", "ismc"}    # GUIDED takes no standoff (a terrain target is a height above the bottom), SURFTRAK
                                 # looks down
CONTROLLERS = {"fuzzy": ["--controller", "fuzzy"], "ismc": ["--controller", "ismc"],
               "ardusub-guided": ["--controller", "ardusub-guided"], "surftrak": []}


def real_bottom(logs: Path) -> dict:
    """The SURFTRAK dive's bottom, its soundings laid along the line at the transect's speed."""
    _, dive = read_dive(logs / REAL_LOG)
    profile = bottom_profile(dive, SPEED, 0.2)
    return {"profile": [[round(float(a), 3), round(float(b), 3)] for a, b in profile]}


def transect(folder: Path, bottom: str, surface: dict, current: float, sounder: str, navigation: str,
             length: float) -> Path:
    """The transect mission: ALTITUDE m above the bottom, or under the ice (bottom "ice") STANDOFF m below it with
    the sounder looking up."""
    under_ice = bottom == "ice"
    kind, height = ("standoff", STANDOFF) if under_ice else ("altitude", ALTITUDE)
    start_depth = parse_surface(surface, "ice" if under_ice else "seafloor").depth_at(0.0, 0.0)
    start_depth += height if under_ice else -height
    echo_sounder = {"preset": sounder, "looking": "up"} if under_ice else sounder
    mission = {"name": "transect", "start": {"position": [0.0, 0.0, round(start_depth, 3)], "heading": 0.0},
               "ramp_time": 3.0,
               "path": [{"hold": 8.0, kind: height}, {"goto": [length, 0.0], kind: height, "speed": SPEED},
                        {"hold": 3.0, kind: height}],
               "environment": {"current": [0.0, current, 0.0], "ice" if under_ice else "seafloor": surface,
                               "navigation": {"preset": navigation, "echo_sounder": echo_sounder}},
               "limits": {"max_depth": 20.0, "max_tracking_error": 3.0, "max_thrust": 40.0}}
    path = folder / "transect.yaml"
    path.write_text(yaml.safe_dump(mission))
    return path


def fly(mission: Path, controller: str, seed: int, args, folder: Path) -> dict:
    start_depth = yaml.safe_load(mission.read_text())["start"]["position"][2]
    if controller == "surftrak":
        return fly_pilot(mission, seed, start_depth, args, folder)
    code, output, end, recorder, m = fly_with_checker(
        mission, [*CONTROLLERS[controller], *args.run_args.split()],
        ["--seed", str(seed), "--start-depth", str(start_depth)], args.speedup, folder)
    if m is None or m["duration_s"] <= 0.0 or not m.get("terrain"):
        return {"code": code, "output": output, "end": end}
    t0 = mission_start(folder / "log" / "ticks.csv")
    return {"code": code, "completed": m["completed"], **m["terrain"],
            "activity": recorder.activity(t0, t0 + m["duration_s"]), "end": end, "output": output}


def fly_pilot(mission: Path, seed: int, start_depth: float, args, folder: Path) -> dict:
    """The SURFTRAK row: `tools/surftrak_pilot.py`'s pilot on one link of a `rov-mav sim-bridge` process in the
    mission's environment, the output recorder on a second."""
    port, checker_port = free_port(), free_port()
    bridge = start_bridge(port, checker_port, args.speedup, mission,
                          ["--seed", str(seed), "--start-depth", str(start_depth)])
    recorder = OutputRecorder(checker_port)
    try:
        figures = fly_surftrak(port, args.speedup, args.length, SPEED, ALTITUDE, folder)
        recorder.finish()
        end = recorder.end_state()
    finally:
        recorder.finish()
        recorder.close()
        bridge_output = stop(bridge)
    error = figures.pop("error", None)
    flown = figures.pop("flown", None)              # vehicle s: the pilot's first and last sample in SURFTRAK
    return {"code": 1 if error else 0, "completed": error is None, **figures,
            "activity": recorder.activity(*flown) if flown else math.nan, "end": end, "output": error or bridge_output}


def _mean(results: list[dict], key: str, scale: float = 100.0) -> float:
    values = [r[key] for r in results if r.get(key) is not None and not math.isnan(r[key])]
    return float(np.mean(values)) * scale if values else math.nan


def _row(cells: list[str], results: list[dict]) -> str:
    done = sum(bool(r.get("completed")) and r["code"] == 0 for r in results)
    worst = max((r.get("max_height_error_true_m") or math.nan) for r in results) * 100
    return ("| " + " | ".join(cells) + f" | {_mean(results, 'rms_height_error_true_m'):.1f} | {worst:.1f} | "
            f"{_mean(results, 'rms_height_error_sounder_m'):.1f} | {_mean(results, 'rms_cross_track_m'):.1f} / "
            f"{_mean(results, 'rms_cross_track_true_m'):.1f} | {_mean(results, 'rms_speed_error_m_s'):.1f} | "
            f"{sum(r.get('strikes', 0) for r in results)} | {_mean(results, 'activity', 1.0):.0f} | "
            f"{done}/{len(results)} | {'; '.join(sorted({r['end'] for r in results}))} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bottoms", default="flat,slope,rough,real")
    parser.add_argument("--currents", default="0,0.2", help="m/s across the line")
    parser.add_argument("--sounders", default="ping", help="ideal, ping")
    parser.add_argument("--navigation", default="dvl", help="the built-in vehicle's: dvl, dvl+ugps, ...")
    parser.add_argument("--controllers", default="fuzzy,ardusub-guided", help=f"of {', '.join(CONTROLLERS)}")
    parser.add_argument("--seeds", default="1")
    parser.add_argument("--length", type=float, default=20.0, help="m of the line (default 20)")
    parser.add_argument("--speedup", type=float, default=5.0)
    parser.add_argument("--run-args", default="", help="more `rov-mav run` options for every run, e.g. "
                                                       "'--thruster-check off'")
    parser.add_argument("--logs", type=Path, default=os.environ.get("ROVMAV_REAL_LOGS"),
                        help="the real logs' folder (default: ROVMAV_REAL_LOGS), for the real bottom")
    parser.add_argument("--keep", type=Path, help="keep every run's log and output in this folder")
    parser.add_argument("--figure", type=Path, help="draw the results page's figure (PNG) from the rows measured "
                                                    "(tools/transect_figure.py)")
    args = parser.parse_args()
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    if "real" in args.bottoms.split(",") and args.logs is None:
        parser.error("the real bottom needs the real logs: --logs DIR or ROVMAV_REAL_LOGS")
    bottoms = {name: BOTTOMS[name] if name != "real" else real_bottom(Path(args.logs))
               for name in args.bottoms.split(",")}
    seeds = [int(s) for s in args.seeds.split(",")]
    print(f"transects of {args.length:g} m at {SPEED:g} m/s, {ALTITUDE:g} m above the bottom; bridge --speedup "
          f"{args.speedup:g}, seeds {args.seeds}; load average before: {os.getloadavg()[0]:.1f}", flush=True)
    print("| bottom | current (m/s) | sounder | navigation | controller | height RMS vs true (cm) | max vs true (cm) | "
          "height RMS vs sounder (cm) | cross-track RMS est / true (cm) | speed RMS (cm/s) | strikes | activity "
          "(us/s) | completed | end state |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|", flush=True)
    notes: list[str] = []
    table: list[str] = []
    rows = itertools.product(bottoms.items(), (float(c) for c in args.currents.split(",")),
                             args.sounders.split(","), args.navigation.split(","), args.controllers.split(","))
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.keep or Path(tmp)
        for (bottom, surface), current, sounder, navigation, controller in rows:
            if bottom == "ice" and controller not in BELOW_ICE:
                continue
            results = []
            for seed in seeds:
                name = f"{bottom} {current:g} {sounder} {navigation} {controller} seed {seed}"
                where = folder / name.replace(" ", "-")
                where.mkdir(parents=True, exist_ok=True)
                mission = transect(where, bottom, surface, current, sounder, navigation, args.length)
                result = fly(mission, controller, seed, args, where)
                output = result.pop("output")
                (where / "run.txt").write_text(output)
                results.append(result)
                if not (result.get("completed") and result["code"] == 0):
                    notes.append(f"{name}: exit {result['code']}, {_stop_reason(output)}")
            table.append(_row([bottom, f"{current:g}", sounder, navigation, controller], results))
            print(table[-1], flush=True)
    print(f"load average after: {os.getloadavg()[0]:.1f}")
    if args.figure is not None:
        draw(read_rows("\n".join(table)), args.figure)
        print(f"figure: {args.figure}")
    for note in notes:
        print(f"not completed: {note}")


if __name__ == "__main__":
    main()
