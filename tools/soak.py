"""Soak: fly the square over and over on the built-in vehicle for an hour of vehicle time, and watch for drift.

A `rov-mav sim-bridge` process and a `rov-mav run` process talk over UDP as on a bench; this script samples both
processes' resident memory (VmRSS) once a wall second and reads the vehicle's own clock from a second bridge link
(ATTITUDE.time_boot_ms, as any station on the link would). After the run, ticks.csv gives the control rate, the loop
latency (telemetry in -> override out) and the tracking error per window of vehicle time. Printed: one row per
window, and the memory growth per hour of vehicle time after the first window (start-up allocations excluded).

Run (an hour of vehicle time at --speedup 10 takes about 6 minutes of wall time on 2 cores):
    .venv/bin/python tools/soak.py [--hours 1] [--speedup 10] [--window 600] [--out out/soak] [--figure PNG]
"""

from __future__ import annotations

import argparse
import csv
import math
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import soak_figure
import yaml
from pymavlink import mavutil

ROOT = Path(__file__).resolve().parents[1]
ROV_MAV = str(Path(sys.executable).with_name("rov-mav"))
MONITOR_SYSID = 201          # not the GCS sysid: it neither drives nor masks


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def looped_square(hours: float, directory: Path) -> Path:
    """missions/square.yaml with its path repeated until it lasts at least `hours` of vehicle time."""
    square = yaml.safe_load((ROOT / "missions" / "square.yaml").read_text())
    loops = math.ceil(hours * 3600.0 / 228.0)        # the square lasts 228 s (its header)
    square["name"] = f"square x{loops}"
    square["path"] = square["path"] * loops
    path = directory / "soak.yaml"
    path.write_text(yaml.safe_dump(square, sort_keys=False))
    return path


def rss_mb(pid: int) -> float:
    """Resident memory of a live process, MB (NaN once it has gone)."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return float("nan")


class Monitor(threading.Thread):
    """Samples (vehicle s, runner MB, bridge MB) once a wall second until stopped."""

    def __init__(self, port: int, runner_pid: int, bridge_pid: int):
        super().__init__(daemon=True)
        self.conn = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=MONITOR_SYSID)
        self.pids = (runner_pid, bridge_pid)
        self.samples: list[tuple[float, float, float]] = []
        self.stopped = threading.Event()

    def run(self) -> None:
        boot_ms = None
        next_sample = time.monotonic()
        while not self.stopped.is_set():
            self.conn.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS, mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
            msg = self.conn.recv_match(type="ATTITUDE", blocking=True, timeout=0.2)
            while msg is not None:
                boot_ms = msg.time_boot_ms
                msg = self.conn.recv_match(type="ATTITUDE", blocking=False)
            if boot_ms is not None and time.monotonic() >= next_sample:
                next_sample += 1.0
                self.samples.append((boot_ms / 1e3, rss_mb(self.pids[0]), rss_mb(self.pids[1])))


def window_rows(ticks: Path, samples: np.ndarray, window: float, boot_offset: float) -> list[dict]:
    """Per window of mission time: control rate, latency, tracking error (ticks.csv) and memory (the samples)."""
    with open(ticks) as f:
        rows = list(csv.DictReader(f))
    col = {k: np.array([float(r[k]) for r in rows]) for k in ("t", "x", "y", "z", "x_d", "y_d", "z_d", "latency",
                                                              "control_rate")}
    flying = col["t"] >= 0
    t = col["t"][flying]
    error = np.sqrt(sum((col[a][flying] - col[a + "_d"][flying]) ** 2 for a in "xyz"))
    out = []
    for start in np.arange(0.0, t[-1], window):
        sel = (t >= start) & (t < start + window)
        if sel.sum() < 2:
            continue
        mem = samples[(samples[:, 0] - boot_offset >= start) & (samples[:, 0] - boot_offset < start + window)]
        span = t[sel][-1] - t[sel][0]
        out.append({"from_min": start / 60.0, "ticks": int(sel.sum()), "rate_hz": (sel.sum() - 1) / span,
                    "rate_min_hz": float(col["control_rate"][flying][sel].min()),
                    "lat_p50_ms": 1e3 * float(np.percentile(col["latency"][flying][sel], 50)),
                    "lat_p99_ms": 1e3 * float(np.percentile(col["latency"][flying][sel], 99)),
                    "rms_cm": 100.0 * float(np.sqrt(np.mean(error[sel] ** 2))),
                    "runner_mb": float(mem[-1, 1]) if len(mem) else float("nan"),
                    "bridge_mb": float(mem[-1, 2]) if len(mem) else float("nan")})
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hours", type=float, default=1.0, help="vehicle hours to fly (default 1)")
    ap.add_argument("--speedup", type=float, default=10.0, help="bridge speedup (default 10)")
    ap.add_argument("--window", type=float, default=600.0, help="report window, vehicle s (default 600)")
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "soak", help="directory for the mission and log")
    ap.add_argument("--figure", type=Path, help="also draw the table as the results page shows it (PNG)")
    a = ap.parse_args()
    a.out.mkdir(parents=True, exist_ok=True)
    mission = looped_square(a.hours, a.out)
    port, monitor_port = free_port(), free_port()
    bridge = subprocess.Popen([ROV_MAV, "sim-bridge", "--listen", f"udpin:127.0.0.1:{port}",
                               "--listen", f"udpin:127.0.0.1:{monitor_port}", "--speedup", f"{a.speedup:g}",
                               "--start-depth", "1"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wall0 = time.monotonic()
    try:
        run = subprocess.Popen([ROV_MAV, "run", "--target", f"udpout:127.0.0.1:{port}", str(mission),
                                "--log", str(a.out / "log"), "--rerun", "off"],
                               stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        monitor = Monitor(monitor_port, run.pid, bridge.pid)
        monitor.start()
        output = run.communicate()[0]
        monitor.stopped.set()
        monitor.join()
    finally:
        bridge.terminate()
        bridge.wait(30)
    wall = time.monotonic() - wall0
    print("\n".join(output.splitlines()[-6:]))
    if run.returncode != 0:
        print(f"soak: the run exited with {run.returncode}", file=sys.stderr)
        return 1
    samples = np.array(monitor.samples)
    ticks = a.out / "log" / "ticks.csv"
    rows = window_rows(ticks, samples, a.window, mission_start_boot_s(ticks, samples))
    print(f"\nflown: {rows[-1]['from_min'] + a.window / 60:.0f} min of vehicle time in {wall:.0f} s of wall time "
          f"at --speedup {a.speedup:g}\n")
    table = ["| from (min) | control rate (Hz) | min 1-s rate (Hz) | latency p50 / p99 (ms) | RMS error (cm) "
             "| runner RSS (MB) | bridge RSS (MB) |", "|---:|---:|---:|---:|---:|---:|---:|"]
    table += [f"| {r['from_min']:.0f} | {r['rate_hz']:.2f} | {r['rate_min_hz']:.0f} | {r['lat_p50_ms']:.2f} / "
              f"{r['lat_p99_ms']:.2f} | {r['rms_cm']:.2f} | {r['runner_mb']:.1f} | {r['bridge_mb']:.1f} |" for r in rows]
    print("\n".join(table))
    if a.figure:
        soak_figure.draw(soak_figure.read_rows("\n".join(table)), a.figure)
    if len(rows) >= 3:
        hours = (rows[-1]["from_min"] - rows[0]["from_min"]) / 60.0
        for who in ("runner", "bridge"):
            growth = (rows[-1][f"{who}_mb"] - rows[0][f"{who}_mb"]) / hours
            print(f"{who} memory growth after the first window: {growth:+.1f} MB per vehicle hour")
    return 0


def mission_start_boot_s(ticks: Path, samples: np.ndarray) -> float:
    """The vehicle's boot time (s) at mission time 0, aligned on the run's end: the last memory sample is taken
    just after the run exits, a few vehicle seconds (its safe stop) after its last tick."""
    with open(ticks) as f:
        last_t = float(list(csv.DictReader(f))[-1]["t"])
    return float(samples[-1, 0]) - last_t


if __name__ == "__main__":
    sys.exit(main())
