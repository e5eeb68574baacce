"""Measure: how the controllers fly on a dive's navigation, against the truth and against the estimate they fly on.

For every mission (default: the square and the under-ice survey) x navigation (ideal, dvl, ugps, dvl+ugps: the
built-in vehicle's `--navigation`) x row (fuzzy and ismc on the vehicle's estimate and on `--estimator model`,
ardusub-guided on ArduSub's own) x seed (the bridge's `--seed`: its sensors' draws), it starts `rov-mav run --log
--metrics` against a `rov-mav sim-bridge` process on its own link, and a checker station on a second link of the
vehicle that asks for SERVO_OUTPUT_RAW at OUTPUT_RATE Hz on its link and records it, so every row's thruster activity
(mean over the eight outputs of sum |delta PWM| per second, `mission.metrics.pwm_activity`) is measured the same way,
from what the vehicle reports, whatever drives the outputs; after the run it reads the end state. Prints a markdown
table: per mission, navigation and row, the means over the seeds of the RMS position error against the truth
(SIM_STATE) and against the estimate flown on, the worst max against the truth, the estimate's own RMS error against
the truth (and the vehicle's, for --estimator model), heading RMS, activity, control rate, runs completed, and the end
states. Run:
    .venv/bin/python tools/navigation_table.py [--missions square,under_ice_survey] [--navigation ugps,dvl+ugps]
                                                [--rows fuzzy,fuzzy/model,guided] [--seeds 1,2] [--speedup 5]
                                                [--figure docs/results/figures/navigation.png]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
from pymavlink import mavutil

sys.path.insert(0, str(Path(__file__).resolve().parent))
from link_faults import ROV_MAV, RUN_WAIT, Checker, free_port, runner_calling, stop  # noqa: E402
from navigation_figure import draw, read_rows  # noqa: E402
from vehicle_faults import mission_start  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from rov_mav.mission.metrics import pwm_activity  # noqa: E402

OUTPUT_RATE = 50.0               # Hz of SERVO_OUTPUT_RAW on the checker's link
ROWS = {                         # name -> run options
    "fuzzy": ["--controller", "fuzzy"],
    "fuzzy/model": ["--controller", "fuzzy", "--estimator", "model"],
    "ismc": ["--controller", "ismc"],
    "ismc/model": ["--controller", "ismc", "--estimator", "model"],
    "guided": ["--controller", "ardusub-guided"],
}
START_DEPTH = {"square": 1.0, "under_ice_survey": 5.0}   # m: where each mission's vehicle boots (its start depth)


class OutputRecorder(Checker):
    """The checker station, recording SERVO_OUTPUT_RAW at OUTPUT_RATE on its own link while the run flies."""

    def __init__(self, port: int):
        super().__init__(port)
        self.samples: list[tuple[float, list[int]]] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._record, daemon=True)
        self._thread.start()

    def _record(self) -> None:
        mav = mavutil.mavlink
        asked = 0.0
        while not self._stop.is_set():
            if time.monotonic() - asked > 2.0:      # the vehicle may not be up yet, or may have rebooted
                self.conn.mav.heartbeat_send(mav.MAV_TYPE_GCS, mav.MAV_AUTOPILOT_INVALID, 0, 0, mav.MAV_STATE_ACTIVE)
                self.conn.mav.command_long_send(1, 1, mav.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                                                mav.MAVLINK_MSG_ID_SERVO_OUTPUT_RAW, 1e6 / OUTPUT_RATE, 0, 0, 0, 0, 0)
                asked = time.monotonic()
            msg = self.conn.recv_match(type="SERVO_OUTPUT_RAW", blocking=True, timeout=0.2)
            if msg is not None:
                self.samples.append((msg.time_usec * 1e-6, [getattr(msg, f"servo{n}_raw") for n in range(1, 9)]))

    def finish(self) -> None:
        self._stop.set()
        self._thread.join()

    def activity(self, start: float, end: float) -> float:
        rows = [(t, pwm) for t, pwm in self.samples if start <= t <= end]
        if len(rows) < 2:
            return math.nan
        return pwm_activity(np.array([t for t, _ in rows]), np.array([p for _, p in rows], dtype=float))


def start_bridge(port: int, checker_port: int, speedup: float, mission: Path, options: list[str]) -> subprocess.Popen:
    """A `rov-mav sim-bridge` process in `mission`'s environment with `options`, listening on `port` (the flight's
    link) and `checker_port` (the output recorder's)."""
    return subprocess.Popen([ROV_MAV, "sim-bridge", "--listen", f"udpin:127.0.0.1:{port}", "--listen",
                             f"udpin:127.0.0.1:{checker_port}", "--speedup", str(speedup), "--environment",
                             str(mission), *options], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def fly_with_checker(mission: Path, run_options: list[str], bridge_options: list[str], speedup: float,
                     folder: Path) -> tuple[int, str, str, OutputRecorder | None, dict | None]:
    """`rov-mav run --target` of `mission` with `run_options` against a `rov-mav sim-bridge` process (its
    environment the mission's, with `bridge_options`) on its own link, and the output recorder on a second link of
    the vehicle: (exit code, the run's output, the end state, the recorder, metrics.json or None). The log and the
    metrics go to `folder`."""
    port, checker_port = free_port(), free_port()
    log, metrics = folder / "log", folder / "metrics.json"
    runner = subprocess.Popen([ROV_MAV, "run", "--target", f"udpout:127.0.0.1:{port}", str(mission), "--log", str(log),
                               "--metrics", str(metrics), "--rerun", "off", "--heartbeat-timeout", "120",
                               *run_options], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    bridge = recorder = None
    end, output = "?", ""
    try:
        runner_calling(port)
        bridge = start_bridge(port, checker_port, speedup, mission, bridge_options)
        recorder = OutputRecorder(checker_port)
        output = runner.communicate(timeout=RUN_WAIT)[0]
        recorder.finish()
        end = recorder.end_state()
    finally:
        if runner.poll() is None:
            output = stop(runner)
        if recorder is not None:
            recorder.finish()
            recorder.close()
        if bridge is not None:
            stop(bridge)
    return runner.returncode, output, end, recorder, json.loads(metrics.read_text()) if metrics.exists() else None


def fly(mission: Path, navigation: str, row: str, seed: int, args, folder: Path) -> dict:
    code, output, end, recorder, m = fly_with_checker(
        mission, [*ROWS[row], *args.run_args.split()],
        ["--navigation", navigation, "--seed", str(seed), "--start-depth", str(START_DEPTH.get(mission.stem, 1.0))],
        args.speedup, folder)
    if m is None or m["duration_s"] <= 0.0:      # stopped before the mission began (in its lead-in, or earlier)
        return {"code": code, "output": output, "end": end}
    t0, duration = mission_start(folder / "log" / "ticks.csv"), m["duration_s"]
    return {"code": code, "completed": m["completed"], "truth": m.get("rms_position_error_truth_m"),
            "truth_max": m.get("max_position_error_truth_m"), "estimate": m["rms_position_error_m"],
            "own": m.get("rms_estimate_error_truth_m"), "vehicle": m.get("rms_vehicle_estimate_error_truth_m"),
            "heading": m["rms_attitude_error_rad"], "rate": m["loop"]["control_rate_hz"],
            "activity": recorder.activity(t0, t0 + duration), "end": end, "output": output}


def _stop_reason(output: str) -> str:
    """What the run said when it stopped (its first "stopping:" line), else its last line."""
    lines = [line for line in output.splitlines() if line.strip()]
    said = [line.split("stopping:", 1)[1].strip() for line in lines if "stopping:" in line]
    return said[0] if said else (lines[-1].strip() if lines else "no output")


def _mean(results: list[dict], key: str) -> float:
    values = [r[key] for r in results if r.get(key) is not None and not math.isnan(r[key])]
    return float(np.mean(values)) if values else math.nan


def _row(mission: str, navigation: str, row: str, results: list[dict]) -> str:
    done = sum(bool(r.get("completed")) and r["code"] == 0 for r in results)
    own = _mean(results, "own") * 100
    vehicle = _mean(results, "vehicle") * 100
    estimate_cell = f"{own:.1f}" + (f" (vehicle's {vehicle:.1f})" if row.endswith("/model") else "")
    ends = sorted({r["end"] for r in results})
    return (f"| {mission} | {navigation} | {row} | {_mean(results, 'truth') * 100:.1f} | "
            f"{max((r.get('truth_max') or math.nan) for r in results) * 100:.1f} | {_mean(results, 'estimate') * 100:.1f} | "
            f"{estimate_cell} | {math.degrees(_mean(results, 'heading')):.2f} | {_mean(results, 'activity'):.0f} | "
            f"{_mean(results, 'rate'):.1f} | {done}/{len(results)} | {'; '.join(ends)} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--missions", default="square,under_ice_survey")
    parser.add_argument("--navigation", default="ideal,dvl,ugps,dvl+ugps")
    parser.add_argument("--rows", default=",".join(ROWS), help=f"of {', '.join(ROWS)}")
    parser.add_argument("--seeds", default="1,2")
    parser.add_argument("--speedup", type=float, default=5.0)
    parser.add_argument("--run-args", default="", help="more `rov-mav run` options for every row, e.g. "
                                                         "\"--velocity-blend 0.3\"")
    parser.add_argument("--keep", type=Path, help="keep every run's log and output in this folder")
    parser.add_argument("--figure", type=Path, help="draw the results page's figure (PNG) from the rows measured "
                                                    "(tools/navigation_figure.py)")
    args = parser.parse_args()
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    seeds = [int(s) for s in args.seeds.split(",")]
    print(f"bridge --speedup {args.speedup:g}, seeds {args.seeds}, SERVO_OUTPUT_RAW at {OUTPUT_RATE:g} Hz on a "
          f"checker's link; run options added: {args.run_args or 'none'}; load average before: "
          f"{os.getloadavg()[0]:.1f}", flush=True)
    print("| mission | navigation | controller / estimator | RMS vs truth (cm) | max vs truth (cm) | RMS vs estimate "
          "(cm) | estimate's own RMS vs truth (cm) | heading RMS (deg) | activity (us/s) | rate (Hz) | completed | "
          "end state |\n|---|---|---|---|---|---|---|---|---|---|---|---|", flush=True)
    notes: list[str] = []
    table: list[str] = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.keep or Path(tmp)
        for mission in args.missions.split(","):
            path = ROOT / "missions" / f"{mission}.yaml"
            for navigation in args.navigation.split(","):
                for row in args.rows.split(","):
                    if navigation == "ideal" and row.endswith("/model"):
                        continue     # no source on the link: the run's own estimate would be the vehicle's
                    results = []
                    for seed in seeds:
                        where = folder / f"{mission}-{navigation}-{row.replace('/', '-')}-{seed}"
                        where.mkdir(parents=True, exist_ok=True)
                        result = fly(path, navigation, row, seed, args, where)
                        output = result.pop("output")
                        (where / "run.txt").write_text(output)
                        results.append(result)
                        if not (result.get("completed") and result["code"] == 0):
                            notes.append(f"{mission} {navigation} {row} seed {seed}: exit {result['code']}, "
                                         f"{_stop_reason(output)}")
                    table.append(_row(mission, navigation, row, results))
                    print(table[-1], flush=True)
    print(f"load average after: {os.getloadavg()[0]:.1f}")
    for note in notes:
        print(f"not completed: {note}")
    if args.figure is not None:
        draw(read_rows("\n".join(table)), args.figure)
        print(f"figure: {args.figure}")


if __name__ == "__main__":
    main()
