"""Measure: how soon a run hands the vehicle to a pilot who joins mid-dive on another link of the vehicle.

Per trial: a `rov-mav sim-bridge` process with two links, `rov-mav run` flying a long straight line on the first,
and at mission t ~ 10 s a pilot station (sysid 255, component 190 - the run's own ids, so the vehicle forwards it
nothing - silent until then) on the second, sending MANUAL_CONTROL x = 600 at 25 Hz of vehicle time. The pilot's
station reads the vehicle's time (ATTITUDE at 50 Hz on its link, asked before it starts) when its first MANUAL_CONTROL
goes; the run's log gives the vehicle time of its last tick. Prints per trial the delay from the pilot's first
message to the run's last command, the run's exit status and what it named; then min / median / max.

    .venv/bin/python tools/pilot_join.py [--trials 5] [--speedup 2]
"""

from __future__ import annotations

import argparse
import csv
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
from pymavlink import mavutil

sys.path.insert(0, str(Path(__file__).resolve().parent))
from link_faults import ROV_MAV, free_port, stop  # noqa: E402

MISSION = """name: line
start: {position: [0.0, 0.0, 1.0], heading: 0.0}
path:
  - {goto: [40.0, 0.0, 1.0], speed: 0.2}
"""
JOIN_AT = "t    10.0 s"            # the run's status line at mission t = 10 s
STICK = (600, 0, 500, 0)          # MANUAL_CONTROL x, y, z, r
RATE = 25.0                       # Hz of vehicle time


def trial(workdir: Path, speedup: float) -> tuple[float, int, str]:
    """(delay in vehicle s from the pilot's first MANUAL_CONTROL to the run's last tick, exit status, stop line)."""
    mission, log = workdir / "line.yaml", workdir / "log"
    mission.write_text(MISSION)
    run_port, pilot_port = free_port(), free_port()
    bridge = subprocess.Popen([ROV_MAV, "sim-bridge", "--listen", f"udpin:127.0.0.1:{run_port}", "--listen",
                               f"udpin:127.0.0.1:{pilot_port}", "--speedup", str(speedup), "--start-depth", "1"],
                              stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)
    run = subprocess.Popen([ROV_MAV, "run", "--target", f"udpout:127.0.0.1:{run_port}", str(mission), "--log",
                            str(log), "--rerun", "off", "--heartbeat-timeout", "60"],
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines: list[str] = []
    joined = threading.Event()

    def read() -> None:
        for line in run.stdout:
            lines.append(line)
            if JOIN_AT in line:
                joined.set()
    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    pilot = mavutil.mavlink_connection(f"udpout:127.0.0.1:{pilot_port}", source_system=255, source_component=190)
    try:
        if not joined.wait(240.0):
            raise RuntimeError("the run never reached mission t = 10 s:\n" + "".join(lines))
        mav = pilot.mav
        mav.command_long_send(1, 1, mavutil.mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                              mavutil.mavlink.MAVLINK_MSG_ID_ATTITUDE, 20000, 0, 0, 0, 0, 0)
        first = None
        deadline = time.monotonic() + 3.0
        while time.monotonic() < deadline and (first := pilot.recv_match(type="ATTITUDE", blocking=True,
                                                                           timeout=0.5)) is None:
            pass
        if first is None:
            raise RuntimeError("the pilot's link never got an ATTITUDE from the vehicle within 3 s of asking")
        period = 1.0 / (RATE * speedup)
        started = None
        while run.poll() is None and time.monotonic() < deadline + 60.0:
            while (m := pilot.recv_match(type="ATTITUDE", blocking=False)) is not None:
                first = m
            if started is None:
                started = first.time_boot_ms / 1000.0
            mav.manual_control_send(1, *STICK, 0)
            time.sleep(period)
        status = run.wait(timeout=60.0)
        reader.join(5.0)
    finally:
        pilot.close()
        stop(bridge)
        if run.poll() is None:
            stop(run)
    with open(log / "ticks.csv") as f:
        rows = list(csv.DictReader(f))
    last = float(rows[-1]["vehicle_time"])
    said = next((line.strip() for line in lines if "stopping:" in line), "(no stop line)")
    return last - started, status, said


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=5)
    parser.add_argument("--speedup", type=float, default=2.0)
    args = parser.parse_args()
    print(f"bridge --speedup {args.speedup:g}, {args.trials} trials, pilot MANUAL_CONTROL x=600 at {RATE:g} Hz on "
          f"its own link; load average before: {open('/proc/loadavg').read().split()[0]}")
    delays = []
    for k in range(args.trials):
        with tempfile.TemporaryDirectory() as d:
            delay, status, said = trial(Path(d), args.speedup)
        delays.append(delay)
        print(f"trial {k + 1}: {delay:.2f} s of vehicle time, exit {status}: {said}", flush=True)
    print(f"delay (vehicle s): min {min(delays):.2f}, median {float(np.median(delays)):.2f}, max {max(delays):.2f}; "
          f"load average after: {open('/proc/loadavg').read().split()[0]}")


if __name__ == "__main__":
    main()
