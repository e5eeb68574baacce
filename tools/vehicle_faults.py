"""Measure: a mission flown by `rov-mav run` against the built-in vehicle while the vehicle itself fails.

For every fault (default: thruster 3 dead, stuck at 1700 us, weak x0.3 and reversed; a reboot; a leak with
FS_LEAK_ENABLE 2; a battery sagging to a critical level with BATT_FS_CRT_ACT 3 (SURFACE); the position source lost;
the depth sensor lost) it starts `rov-mav run` (--log), then, once the runner is calling, `rov-mav sim-bridge` with
`--vehicle-faults` striking at mission time --at (default 60 s: on the square, just into its second side; the
vehicle time of the mission's start is taken from a healthy run first, the table's first row) and a second link for
a checker, which reads the vehicle's end state after the run: armed, mode, SERVO_OUTPUT_RAW, SERVO1..8_FUNCTION and
the GCS sysid. Prints a markdown table: the fault, when it struck (mission s), what the run said and when (vehicle s
after the fault), completed or how it ended (exit status), RMS and max position error from the fault on (from the
run's ticks.csv: the vehicle's reported position, here its true one plus the mission's sensor noise), and the end
state. Run:
    .venv/bin/python tools/vehicle_faults.py [--mission missions/square.yaml] [--speedup 5] [--at 60]
                                             [--only dead,reboot] [--keep DIR] [--figure PNG]
"""

from __future__ import annotations

import argparse
import csv
import math
import os
import re
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import vehicle_faults_figure  # noqa: E402
from link_faults import ROV_MAV, RUN_WAIT, Checker, free_port, runner_calling, stop  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
MODES = {0: "STABILIZE", 1: "ACRO", 2: "ALT_HOLD", 4: "GUIDED", 9: "SURFACE", 16: "POSHOLD", 19: "MANUAL"}
# name -> (the fault at vehicle time T, the vehicle's parameters for it)
FAULTS = {
    "healthy": ("", ()),
    "dead": ("thruster=3:dead@{T}s", ()),
    "stuck": ("thruster=3:stuck=1700@{T}s", ()),
    "weak": ("thruster=3:weak=0.3@{T}s", ()),
    "reversed": ("thruster=3:reversed@{T}s", ()),
    "reboot": ("reboot@{T}s", ()),
    "leak": ("leak@{T}s", ("FS_LEAK_ENABLE=2",)),
    "battery": ("battery=0.2V/s@{T}s", ("BATT_CRT_VOLT=15.5", "BATT_FS_CRT_ACT=3", "BATT_LOW_TIMER=1")),
    "navigation-lost": ("navigation-lost@{T}s", ()),
    "depth-sensor": ("depth-sensor@{T}s", ()),
}


def end_state(checker: Checker) -> str:
    heartbeat = checker.fresh("HEARTBEAT")
    armed = bool(heartbeat.base_mode & 128)
    servo = checker.fresh("SERVO_OUTPUT_RAW")
    outputs = [getattr(servo, f"servo{n}_raw") for n in range(1, 9)]
    functions = [checker.param(f"SERVO{n}_FUNCTION") for n in range(1, 9)]
    gcs = checker.param("MAV_GCS_SYSID")
    return ", ".join(["armed" if armed else "disarmed", MODES.get(heartbeat.custom_mode, str(heartbeat.custom_mode)),
                      "neutral" if outputs == [1500] * 8 else f"outputs {outputs}",
                      "motors" if functions == list(range(33, 41)) else f"functions {functions}", f"GCS {gcs}"])


def errors_after(ticks: Path, at: float) -> tuple[float, float]:
    """(RMS, max) position error in cm over the mission ticks from mission time `at` on."""
    squares = []
    with ticks.open() as f:
        for row in csv.DictReader(f):
            if float(row["t"]) >= at:
                squares.append(sum((float(row[d]) - float(row[f"{d}_d"])) ** 2 for d in ("x", "y", "z")))
    if not squares:
        return math.nan, math.nan
    return 100 * math.sqrt(sum(squares) / len(squares)), 100 * math.sqrt(max(squares))


def mission_start(ticks: Path) -> float:
    """The vehicle time of the mission's start (its first tick at mission time >= 0)."""
    with ticks.open() as f:
        for row in csv.DictReader(f):
            if float(row["t"]) >= 0:
                return float(row["vehicle_time"]) - float(row["t"])
    raise RuntimeError(f"{ticks}: the mission never started")


def fly(name: str, strike: float | None, args, folder: Path) -> dict:
    """One run with fault `name` striking at vehicle time `strike`."""
    fault, params = FAULTS[name]
    port, clean = free_port(), free_port()
    log = folder / name
    runner = subprocess.Popen([ROV_MAV, "run", "--target", f"udpout:127.0.0.1:{port}", str(args.mission), "--log",
                               str(log), "--rerun", "off", "--heartbeat-timeout", "120"],
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    bridge = None
    end = "?"
    try:
        runner_calling(port)
        command = [ROV_MAV, "sim-bridge", "--listen", f"udpin:127.0.0.1:{port}", "--listen", f"udpin:127.0.0.1:{clean}",
                   "--speedup", str(args.speedup), "--environment", str(args.mission), "--start-depth",
                   str(args.start_depth)]
        if fault:
            command += ["--vehicle-faults", fault.format(T=f"{strike:.2f}")]
        for param in params:
            command += ["--param", param]
        bridge = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        output = runner.communicate(timeout=RUN_WAIT)[0]
        checker = Checker(clean)
        try:
            end = end_state(checker)
        finally:
            checker.close()
    finally:
        if runner.poll() is None:
            output = stop(runner)
        bridge_out = stop(bridge) if bridge is not None else ""
    if args.keep is not None:
        args.keep.mkdir(parents=True, exist_ok=True)
        (args.keep / f"run-{name}.txt").write_text(output)
        (args.keep / f"bridge-{name}.txt").write_text(bridge_out)
    ticks = log / "ticks.csv"
    start = mission_start(ticks)
    at = strike - start if strike is not None else 0.0
    said = _said(output, name)
    rms, peak = errors_after(ticks, at)
    reason = re.search(r"stopping: (.*)", output)
    return {"start": start, "at": at, "said": said, "code": runner.returncode,
            "reason": reason.group(1) if reason else "?", "rms": rms, "max": peak, "end": end,
            "detected": _detected(output, said, strike, start)}


def _said(output: str, name: str) -> str:
    """The run's first line about the fault."""
    if name in ("dead", "stuck", "weak", "reversed"):
        found = re.findall(r"WARNING: (thruster \d [a-z]+).*?seen at vehicle", output)
        return "; then ".join(found) if found else "nothing"
    if name == "reboot":
        found = re.search(r"(?:stopping|WARNING): (the vehicle rebooted \(.*?\))(?:, first seen as: (.*))?", output)
        if found is None:
            return "nothing"
        return found.group(1) + (f", first seen as {found.group(2)}" if found.group(2) else ", seen at once")
    found = re.search(r"stopping: (.*)", output)
    return found.group(1) if found else "nothing"


def _detected(output: str, said: str, strike: float | None, start: float) -> float:
    """Vehicle s from the fault to the run's answer (its thruster line, or its stop)."""
    if strike is None or said == "nothing" or said.startswith("the vehicle rebooted"):
        return math.nan       # mission time does not run through the vehicle's silence: see the exit-time test
    seen = re.search(r"vehicle t=([\d.]+) s", output)
    if seen is not None and said.startswith("thruster"):
        return float(seen.group(1)) - strike
    stopped = re.search(r"\[\s*(-?[\d.]+)\] stopping:", output)
    return float(stopped.group(1)) + start - strike if stopped else math.nan


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mission", type=Path, default=ROOT / "missions" / "square.yaml")
    parser.add_argument("--speedup", type=float, default=5.0)
    parser.add_argument("--start-depth", type=float, default=1.0, help="the vehicle's depth at boot, m")
    parser.add_argument("--at", type=float, default=60.0, help="mission time at which each fault strikes, s")
    parser.add_argument("--only", default=",".join(n for n in FAULTS if n != "healthy"),
                        help=f"faults to fly, of {', '.join(FAULTS)}")
    parser.add_argument("--keep", type=Path, help="write every run's and bridge's output to this folder")
    parser.add_argument("--figure", type=Path, help="also draw the table as the results page shows it (PNG)")
    args = parser.parse_args()
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    print(f"mission {args.mission.name}, bridge --speedup {args.speedup:g}, faults at mission t = {args.at:g} s; load "
          f"average before: {os.getloadavg()[0]:.1f}", flush=True)
    table = ["| fault | struck at (mission s) | what the run said | after (vehicle s) | completed / exit | RMS / max "
             "error after it | end state |", "|---|---|---|---|---|---|---|"]
    print("\n".join(table), flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        healthy = fly("healthy", None, args, Path(tmp))
        table.append(f"| none | - | - | - | {'yes' if healthy['code'] == 0 else 'no: ' + healthy['reason']} / "
                     f"{healthy['code']} | {healthy['rms']:.2f} / {healthy['max']:.1f} cm | {healthy['end']} |")
        print(table[-1], flush=True)
        for name in args.only.split(","):
            r = fly(name, healthy["start"] + args.at, args, Path(tmp))
            done = "yes" if r["code"] == 0 else "no"
            table.append(f"| {FAULTS[name][0].replace('@{T}s', '')} | {r['at']:.1f} | {r['said']} | "
                         f"{r['detected']:.2f} | {done} / {r['code']} | {r['rms']:.2f} / {r['max']:.1f} cm | {r['end']} |")
            print(table[-1], flush=True)
    print(f"load average after: {os.getloadavg()[0]:.1f}")
    if args.figure:
        vehicle_faults_figure.draw(vehicle_faults_figure.read_rows("\n".join(table)), args.figure)


if __name__ == "__main__":
    main()
