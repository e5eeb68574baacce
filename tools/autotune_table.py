"""Autotune on vehicles unlike the shipped model: for each, the square flown with the shipped model and gains, then
`rov-mav autotune`, then the square again with the vehicle file and gains it kept; all against one `rov-mav sim-bridge`
process whose vehicle is that one, in the square's water (its constant disturbance, Eq. 3.2). Printed per vehicle:
the square's RMS and max position error before and after (the built-in vehicle's ideal navigation: its position is
the truth), their ratio, what autotune decided, its tune's wall time and the procedure's vehicle time at 1x
(flights plus the tune's wall time), and the fit's surge and heave added mass against the vehicle's.

The vehicles (each from the shipped BlueROV2 Heavy):
  payload   3 kg low and aft (0.15 m behind, 0.10 m below the centre) with 3 L of foam high and aft to match
  weak      thruster 1 (front right, horizontal) gives 70 % of its thrust
  heavier   added mass and damping 40 % above the model
Run:
    .venv/bin/python tools/autotune_table.py [--vehicles payload,weak,heavier] [--speedup 5] [--budget 90]
                                             [--keep DIR] [--figure PNG]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import autotune_figure  # noqa: E402
from link_faults import ROV_MAV, free_port  # noqa: E402

from rov_mav.model.vehicle import Vehicle, load_vehicle, save_vehicle  # noqa: E402

PAYLOAD, PAYLOAD_AT = 3.0, np.array([-0.15, 0.0, 0.10])     # kg, m from the centre (x forward, z down)
FOAM_AT = np.array([-0.15, 0.0, -0.10])                     # m: the foam that floats it, high and aft
SQUARE_MAX_DEPTH = 10.0   # m: the square's own 3 m (a pool) would refuse a vehicle that sank there between flights
RUN_WAIT = 1800.0                                           # wall s for a command


def payload(v: Vehicle) -> Vehicle:
    """3 kg at PAYLOAD_AT and 3 L of foam at FOAM_AT (net buoyancy unchanged): mass, centre of gravity and of
    buoyancy, inertia about the new centre of gravity (parallel axes)."""
    mass, foam = v.mass + PAYLOAD, PAYLOAD / v.water_density
    cg = (v.mass * v.center_of_gravity + PAYLOAD * PAYLOAD_AT) / mass
    cb = (v.volume * v.center_of_buoyancy + foam * FOAM_AT) / (v.volume + foam)

    def about(point, m, centre):
        r = np.asarray(point) - centre
        return m * (r @ r * np.eye(3) - np.outer(r, r))
    inertia = v.inertia_tensor + about(v.center_of_gravity, v.mass, cg) + about(PAYLOAD_AT, PAYLOAD, cg)
    return replace(v, name="payload", mass=mass, volume=v.volume + foam, center_of_gravity=cg,
                   center_of_buoyancy=cb, inertia_tensor=inertia)


def weak(v: Vehicle) -> Vehicle:
    scale = np.array(v.per_thruster_scale, dtype=float)
    scale[0] = 0.7
    return replace(v, name="weak", per_thruster_scale=scale)


def heavier(v: Vehicle) -> Vehicle:
    return replace(v, name="heavier", added_mass=v.added_mass * 1.4, linear_damping=v.linear_damping * 1.4,
                   quadratic_damping=v.quadratic_damping * 1.4)


VEHICLES = {"payload": payload, "weak": weak, "heavier": heavier}


def command(args: list[str], log: Path) -> int:
    with open(log, "w") as out:
        return subprocess.run([ROV_MAV, *args], stdout=out, stderr=subprocess.STDOUT, timeout=RUN_WAIT).returncode


def square(target: str, folder: Path, *options: str) -> dict:
    folder.mkdir(parents=True, exist_ok=True)
    code = command(["run", "--target", target, "square", "--rerun", "off", "--metrics", str(folder / "metrics.json"),
                    "--log", str(folder / "log"), "--max-depth", f"{SQUARE_MAX_DEPTH:g}", *options],
                   folder / "output.txt")
    metrics = json.loads((folder / "metrics.json").read_text()) if (folder / "metrics.json").exists() else {}
    return {"code": code, "rms": metrics.get("rms_position_error_m", np.nan) * 100,
            "max": metrics.get("max_position_error_m", np.nan) * 100}


def one_vehicle(name: str, args: argparse.Namespace, folder: Path) -> dict:
    vehicle_file = folder / f"{name}.yaml"
    truth = VEHICLES[name](load_vehicle())
    save_vehicle(truth, vehicle_file)
    port = free_port()
    target = f"udpout:127.0.0.1:{port}"
    bridge = subprocess.Popen([ROV_MAV, "sim-bridge", "--listen", f"udpin:127.0.0.1:{port}", "--speedup",
                               f"{args.speedup:g}", "--vehicle", str(vehicle_file), "--environment", "square",
                               "--start-depth", "1.5"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        time.sleep(2.0)
        before = square(target, folder / "square-shipped")
        out = folder / "autotune"
        started = time.monotonic()
        code = command(["autotune", "--target", target, "--out", str(out), "--budget", f"{args.budget:g}"],
                       folder / "autotune.txt")
        wall = time.monotonic() - started
        kept = code == 0
        options = ["--vehicle", str(out / "vehicle.yaml"), "--gains", str(out / "gains.yaml")] if kept else []
        after = square(target, folder / "square-autotuned", *options) if code in (0, 4) else None
    finally:
        bridge.terminate()
        bridge.wait(30)
    stopped = re.search(r"stopped at step \d of 6 \((\w+)\)", (folder / "autotune.txt").read_text())
    return {"vehicle": name, "before": before, "after": after, "code": code, "wall": wall,
            "stopped": stopped.group(1) if stopped else "?", "procedure": procedure_time(out), "fit": fit(out, truth)}


def procedure_time(out: Path) -> float:
    """Vehicle s of the procedure at 1x: the flights (the run logs' spans) and the tune's wall time."""
    total = 0.0
    for log in ("excite", "check-old", "check-new"):
        ticks = out / log / "ticks.csv"
        if ticks.exists():
            t = np.loadtxt(ticks, delimiter=",", skiprows=1, usecols=0, ndmin=1)
            total += float(t[-1] - t[0]) if t.size else 0.0
    comparison = out / "tune" / "comparison.json"
    if comparison.exists():
        total += json.loads(comparison.read_text())["elapsed_s"]
    return total


def fit(out: Path, truth: Vehicle) -> str:
    if not (out / "vehicle.yaml").exists():
        return "-"
    fitted, shipped = load_vehicle(out / "vehicle.yaml"), load_vehicle()
    return ", ".join(f"{label} {fitted.added_mass[i]:.1f} (vehicle {truth.added_mass[i]:.1f}, model "
                     f"{shipped.added_mass[i]:.1f})" for label, i in (("surge", 0), ("heave", 2)))


OUTCOME = {0: "new gains kept", 4: "not better: old kept"}


def row(r: dict) -> str:
    before, after = r["before"], r["after"]
    tuned = f"{after['rms']:.2f} / {after['max']:.1f}" if after else "-"
    ratio = f"{after['rms'] / before['rms']:.2f}" if after else "-"
    outcome = OUTCOME.get(r["code"], f"stopped at {r['stopped']} (exit {r['code']})")
    return (f"| {r['vehicle']} | {before['rms']:.2f} / {before['max']:.1f} | {tuned} | {ratio} | {outcome} | "
            f"{r['procedure'] / 60:.1f} | {r['fit']} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--vehicles", default=",".join(VEHICLES))
    parser.add_argument("--speedup", type=float, default=5.0)
    parser.add_argument("--budget", type=float, default=90.0, help="autotune --budget, wall s")
    parser.add_argument("--keep", type=Path, help="keep every output in this folder")
    parser.add_argument("--figure", type=Path, help="also draw the table as the results page shows it (PNG)")
    args = parser.parse_args()
    print(f"bridge --speedup {args.speedup:g}, autotune --budget {args.budget:g}; load average before: "
          f"{os.getloadavg()[0]:.1f}", flush=True)
    table = ["| vehicle | square, shipped: RMS / max (cm) | autotuned: RMS / max (cm) | ratio | autotune | procedure "
             "(vehicle min at 1x) | fit: added mass (kg) |", "|---|---|---|---|---|---|---|"]
    print("\n".join(table), flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        root = args.keep or Path(tmp)
        for name in args.vehicles.split(","):
            folder = root / name
            folder.mkdir(parents=True, exist_ok=True)
            table.append(row(one_vehicle(name, args, folder)))
            print(table[-1], flush=True)
    print(f"load average after: {os.getloadavg()[0]:.1f}")
    if args.figure:
        autotune_figure.draw(autotune_figure.read_rows("\n".join(table)), args.figure)


if __name__ == "__main__":
    main()
