"""Fly a mission (the square by default) on ArduPilot's own ArduSub SITL and print the tracking table.

Each run boots a fresh SITL (`rov_mav.sitl`: scratch directory, free instance, ended by its PID), waits for its EKF,
and flies the mission with `rov-mav run --target tcp:...` (its own process, any extra run options after `--`);
`--guided HZ` flies it with `--controller ardusub-guided --guided-rate HZ` (ArduSub's GUIDED controller fed the same
reference). A monitor on SITL's other link records the EKF estimate and SITL's true state (SIM_STATE) throughout.

Printed per run: against the EKF estimate (what the controller sees) on the reference, RMS and max 3D position
error, heading RMS and max, pitch RMS; for rov-mav, tau_hat at the end; against SITL's truth, the RMS 3D error;
and the estimator's floor over the flight (EKF minus truth: horizontal RMS, vertical mean offset and RMS about it,
heading RMS); the achieved speedup (vehicle s per wall s, mean and the slowest 10 s window), the control rate, and
the stalls (state samples more than 60 ms of vehicle time apart, and the longest gap): on a loaded machine the
runner or SITL is sometimes descheduled, and the vehicle then keeps its last command.

    nice .venv/bin/python tools/sitl_square.py [--runs 2] [--speedup 2] [--guided 10] [--param NAME=VALUE ...]
                                               [--mission missions/square.yaml] [--out out/sitl] [--figure PNG]
                                               [-- RUN OPTIONS]
e.g. `-- --vehicle my_vehicle.yaml --controller constant`. SITL from ARDUSUB_SITL (ArduPilot's build/sitl/bin/ardusub).
"""

from __future__ import annotations

import argparse
import csv
import json
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import sitl_figure
from sitl_links import Monitor

from rov_mav.mission.missions import load_mission
from rov_mav.sitl import Sitl, SitlError, binary_from_environment
from rov_mav.units import wrap_angle

ROOT = Path(__file__).resolve().parents[1]
ROV_MAV = str(Path(sys.executable).with_name("rov-mav"))
POSITION_WAIT = 150.0        # wall s for the EKF's first position (about 40 s of vehicle time)
RUN_WAIT = 1800.0            # wall s for a whole flight
LATE = 0.06                  # vehicle s between state samples that counts as a stall (3 periods at 50 Hz)


def tracking(eta: np.ndarray, eta_d: np.ndarray) -> dict:
    """RMS/max 3D position error (cm), heading RMS/max and pitch RMS (deg) of poses (N, 6) against references."""
    e = eta - eta_d
    e[:, 3:] = wrap_angle(e[:, 3:])
    pos = np.linalg.norm(e[:, :3], axis=1) * 100.0
    heading, pitch = np.degrees(np.abs(e[:, 5])), np.degrees(e[:, 4])
    rms = lambda x: float(np.sqrt(np.mean(x ** 2)))   # noqa: E731
    return {"rms_cm": rms(pos), "max_cm": float(pos.max()), "heading_rms_deg": rms(heading),
            "heading_max_deg": float(heading.max()), "pitch_rms_deg": rms(pitch)}


def reference_at(t: np.ndarray, t_ref: np.ndarray, eta_d: np.ndarray) -> np.ndarray:
    """The logged reference (N, 6) at times t by linear interpolation (angles unwrapped first)."""
    out = np.empty((t.size, 6))
    for k in range(6):
        column = np.unwrap(eta_d[:, k]) if k >= 3 else eta_d[:, k]
        out[:, k] = np.interp(t, t_ref, column)
    out[:, 3:] = wrap_angle(out[:, 3:])
    return out


def floor(samples: dict, t0: float, t1: float) -> dict:
    """The estimator against SITL's truth between vehicle times t0 and t1 (the flight)."""
    inside = (samples["t"] >= t0) & (samples["t"] <= t1)
    d = samples["ekf"][inside] - samples["truth"][inside]
    d[:, 3:] = wrap_angle(d[:, 3:])
    horizontal = np.linalg.norm(d[:, :2], axis=1)
    return {"ekf_horizontal_rms_cm": float(np.sqrt(np.mean(horizontal ** 2))) * 100.0,
            "ekf_vertical_offset_cm": float(np.mean(d[:, 2])) * 100.0,
            "ekf_vertical_rms_cm": float(np.std(d[:, 2])) * 100.0,
            "ekf_heading_rms_deg": float(np.degrees(np.sqrt(np.mean(d[:, 5] ** 2)))),
            "ekf_pitch_rms_deg": float(np.degrees(np.sqrt(np.mean(d[:, 4] ** 2))))}


def truth_error(samples: dict, t_ref: np.ndarray, eta_d: np.ndarray, t0: float, t1: float) -> dict:
    """SITL's true pose against the reference over the mission: RMS 3D (cm)."""
    inside = (samples["t"] >= t0) & (samples["t"] <= t1)
    truth = samples["truth"][inside]
    ref = reference_at(samples["t"][inside], t_ref, eta_d)
    return {"truth_rms_cm": tracking(truth, ref)["rms_cm"]}


def read_ticks(path: Path) -> dict[str, np.ndarray]:
    with open(path) as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def fly_runner(sitl: Sitl, mission: Path, run_dir: Path, options: list[str]) -> dict:
    """`rov-mav run` on SITL's SERIAL1; returns its mission-time series and summary."""
    log = run_dir / "log"
    args = [ROV_MAV, "run", "--target", f"tcp:127.0.0.1:{sitl.port1}", str(mission), "--rerun", "off",
            "--log", str(log), "--metrics", str(run_dir / "metrics.json"), *options]
    with open(run_dir / "run.out", "w") as out:
        code = subprocess.run(args, stdout=out, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                              timeout=RUN_WAIT).returncode
    output = (run_dir / "run.out").read_text()
    if code != 0:
        raise RuntimeError(f"rov-mav run exited with {code}: see {run_dir / 'run.out'}\n{output[-1500:]}")
    ticks = read_ticks(log / "ticks.csv")
    flown = ticks["t"] >= 0.0
    dof = ("x", "y", "z", "phi", "theta", "psi")
    loop = json.loads((run_dir / "metrics.json").read_text())["loop"]
    stale = re.search(r"telemetry went stale (\d+) time", output)
    gaps = np.diff(ticks["vehicle_time"][flown])
    return {"t_vehicle": ticks["vehicle_time"][flown],
            "eta": np.column_stack([ticks[d][flown] for d in dof]),
            "eta_d": np.column_stack([ticks[f"{d}_d"][flown] for d in dof]),
            "tau_hat": None if np.isnan(ticks["tau_hat_X"][-1]) else [float(ticks[f"tau_hat_{w}"][-1]) for w in "XYZKMN"],
            "rate_hz": loop["control_rate_hz"], "stale": int(stale.group(1)) if stale else 0,
            "late_ticks": int(np.sum(gaps > LATE)), "longest_gap_ms": float(gaps.max()) * 1000.0}


def fly_guided(sitl: Sitl, mission_path: Path, rate: float, run_dir: Path) -> dict:
    """ArduSub's GUIDED controller through the product path: `rov-mav run --controller ardusub-guided`."""
    return fly_runner(sitl, mission_path, run_dir, ["--controller", "ardusub-guided", "--guided-rate", f"{rate:g}"])


def one_run(args, run_dir: Path, binary: Path) -> dict:
    params = dict(args.param)
    with Sitl(binary, run_dir / "sitl", args.speedup, params=params) as sitl:
        sitl.wait_for_port(sitl.port0)
        monitor = Monitor(sitl.port0)
        monitor.start()
        try:
            monitor.wait_for_position(POSITION_WAIT)
            if args.guided:
                flight = fly_guided(sitl, args.mission, args.guided, run_dir)
            else:
                flight = fly_runner(sitl, args.mission, run_dir, args.run_options)
        finally:
            monitor.stop()
    t0, t1 = float(flight["t_vehicle"][0]), float(flight["t_vehicle"][-1])
    samples = monitor.samples()
    np.savez(run_dir / "monitor.npz", clock=np.array(monitor.clock), **samples)
    row = tracking(flight["eta"], flight["eta_d"])
    row |= truth_error(samples, flight["t_vehicle"], flight["eta_d"], t0, t1)
    row |= floor(samples, t0, t1)
    mean, slowest = monitor.speed(int(t0 * 1000))
    row |= {key: flight[key] for key in ("tau_hat", "rate_hz", "stale", "late_ticks", "longest_gap_ms")}
    row |= {"speedup": mean, "speedup_min": slowest, "voltage": monitor.voltage}
    (run_dir / "row.json").write_text(json.dumps(row, indent=2) + "\n")
    return row


COLUMNS = [("RMS 3D cm", "rms_cm", "{:.2f}"), ("max 3D cm", "max_cm", "{:.2f}"),
           ("hdg RMS deg", "heading_rms_deg", "{:.2f}"), ("hdg max deg", "heading_max_deg", "{:.1f}"),
           ("pitch RMS deg", "pitch_rms_deg", "{:.3f}"), ("truth RMS 3D cm", "truth_rms_cm", "{:.2f}"),
           ("EKF-truth horiz cm", "ekf_horizontal_rms_cm", "{:.2f}"),
           ("EKF-truth vert offset/RMS cm", None, None), ("EKF-truth hdg deg", "ekf_heading_rms_deg", "{:.2f}"),
           ("speedup mean/min", None, None), ("rate Hz", "rate_hz", "{:.1f}"),
           ("gaps > 60 ms", "late_ticks", "{:.0f}"), ("longest gap ms", "longest_gap_ms", "{:.0f}")]


def table_row(label: str, row: dict) -> str:
    cells = [label]
    for _, key, fmt in COLUMNS:
        if key is not None:
            cells.append(fmt.format(row[key]))
    cells.insert(8, f"{row['ekf_vertical_offset_cm']:+.1f} / {row['ekf_vertical_rms_cm']:.1f}")
    cells.insert(10, f"{row['speedup']:.2f} / {row['speedup_min']:.2f}")
    return "| " + " | ".join(cells) + " |"


def print_table(label: str, rows: list[dict]) -> str:
    """Prints the table (and each run's tau_hat); returns the table's markdown."""
    table = ["| run | " + " | ".join(name for name, _, _ in COLUMNS) + " |", "|" + "---|" * (len(COLUMNS) + 1)]
    table += [table_row(f"{label} #{i}", row) for i, row in enumerate(rows, 1)]
    if len(rows) > 1:
        mean = {k: float(np.mean([r[k] for r in rows])) for k in rows[0]
                if isinstance(rows[0][k], (int, float)) and rows[0][k] is not None}
        table.append(table_row(f"{label} mean", mean))
    print("\n".join(table))
    for i, row in enumerate(rows, 1):
        if row["tau_hat"] is not None:
            print(f"run {i}: tau_hat at the end [X Y Z N; K M N N m] = "
                  + ", ".join(f"{v:+.2f}" for v in row["tau_hat"])
                  + f"; watchdog neutral episodes {row['stale']}; battery {row['voltage']} V")
    return "\n".join(table)


def _param(text: str) -> tuple[str, float]:
    name, _, value = text.partition("=")
    try:
        return name.strip(), float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--param wants NAME=VALUE, got {text!r}") from None


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    run_options = argv[argv.index("--") + 1:] if "--" in argv else []
    argv = argv[:argv.index("--")] if "--" in argv else argv
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--mission", type=Path, default=ROOT / "missions" / "square.yaml")
    p.add_argument("--runs", type=int, default=2)
    p.add_argument("--speedup", type=float, default=2.0,
                   help="SITL speedup (default 2: the runner keeps its 50 Hz on a loaded 2-core machine)")
    p.add_argument("--guided", type=float, metavar="HZ", help="fly ArduSub's GUIDED controller at HZ instead")
    p.add_argument("--param", type=_param, action="append", default=[], metavar="NAME=VALUE",
                   help="SITL parameter at boot (e.g. SIM_BARO_RND=0.02)")
    p.add_argument("--label", default=None, help="row label (default: the flight kind)")
    p.add_argument("--out", type=Path, default=ROOT / "out" / "sitl")
    p.add_argument("--figure", type=Path, help="also draw the table as the results page shows it (PNG)")
    args = p.parse_args(argv)
    args.run_options = run_options
    try:
        binary = binary_from_environment()
    except SitlError as exc:
        print(f"sitl_square: {exc}", file=sys.stderr)
        return 2
    if binary is None:
        print("sitl_square: set ARDUSUB_SITL to an ArduSub SITL binary (ArduPilot's build/sitl/bin/ardusub)",
              file=sys.stderr)
        return 2
    label = args.label or (f"GUIDED {args.guided:g} Hz" if args.guided else "rov-mav " + " ".join(run_options))
    stamp = time.strftime("%Y%m%d-%H%M%S")
    rows = []
    for i in range(args.runs):
        run_dir = args.out / f"{stamp}-{i + 1}"
        run_dir.mkdir(parents=True, exist_ok=True)
        started = time.monotonic()
        rows.append(one_run(args, run_dir, binary))
        print(f"run {i + 1}/{args.runs}: {time.monotonic() - started:.0f} s wall, {run_dir}", flush=True)
        print(table_row(label, rows[-1]), flush=True)
    print()
    print("command: " + " ".join(["tools/sitl_square.py", *sys.argv[1:]]))
    table = print_table(label.strip(), rows)
    if args.figure:
        sitl_figure.draw(sitl_figure.read_rows(table), args.figure)
    return 0


if __name__ == "__main__":
    sys.exit(main())
