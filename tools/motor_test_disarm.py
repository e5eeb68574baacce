"""Measure: what a run with `--output motor-test` does when another station disarms the vehicle mid-mission.

A disarmed ArduSub leaves the last test PWMs on the thrusters and every further DO_MOTOR_TEST, refused, keeps the
test alive (ArduSub/motors.cpp): only the run's silence lets the test time out, 0.5 s of vehicle time after its last
command. Per trial: a `rov-mav sim-bridge` process with two links, `rov-mav run --output motor-test --log` flying a
straight line on the first, and at mission t ~ 10 s a station on the second (sysid 200) sends the disarm. From the
run's own MAVLink log (both directions, stamped as sent and received): the first sign of the disarm (a refused
DO_MOTOR_TEST's COMMAND_ACK after an accepted one, or a disarmed HEARTBEAT), how many DO_MOTOR_TEST went after it and
how long after it the last went (wall ms; one control period is 20 ms of vehicle time, 20 / speedup wall ms). From
the second station, in vehicle time: from the disarm's COMMAND_ACK to "Motor test timed out!" and to SERVO_OUTPUT_RAW
all 1500. Prints each trial, then min / median / max.

    .venv/bin/python tools/motor_test_disarm.py [--trials 5] [--speedup 2]
"""

from __future__ import annotations

import argparse
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
  - {goto: [20.0, 0.0, 1.0], speed: 0.2}
"""
DISARM_AT = "t    10.0 s"           # the run's status line at mission t = 10 s
MOTOR_TEST = mavutil.mavlink.MAV_CMD_DO_MOTOR_TEST


def run_log_figures(tlog: Path) -> tuple[int, float]:
    """(DO_MOTOR_TEST sent after the first sign of the disarm, wall ms from that sign to the last one sent)."""
    sent, first_sign, accepted = [], None, False
    conn = mavutil.mavlink_connection(str(tlog))
    while (m := conn.recv_match()) is not None:
        kind, source = m.get_type(), m.get_srcSystem()
        if kind == "COMMAND_LONG" and m.command == MOTOR_TEST and source != 1:
            sent.append(m._timestamp)
        elif source == 1 and kind == "COMMAND_ACK" and m.command == MOTOR_TEST:
            accepted |= m.result == 0
            if accepted and m.result != 0 and first_sign is None:
                first_sign = m._timestamp
        elif source == 1 and kind == "HEARTBEAT" and accepted and not m.base_mode & 128 and first_sign is None:
            first_sign = m._timestamp
    if first_sign is None:
        raise RuntimeError("the run's log shows no refusal and no disarm")
    after = [t for t in sent if t > first_sign]
    return len(after), (max(after) - first_sign) * 1e3 if after else 0.0


def trial(workdir: Path, speedup: float) -> tuple[int, float, float, float, int, str]:
    mission, log = workdir / "line.yaml", workdir / "log"
    mission.write_text(MISSION)
    run_port, station_port = free_port(), free_port()
    bridge = subprocess.Popen([ROV_MAV, "sim-bridge", "--listen", f"udpin:127.0.0.1:{run_port}", "--listen",
                               f"udpin:127.0.0.1:{station_port}", "--speedup", str(speedup), "--start-depth", "1"],
                              stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)
    run = subprocess.Popen([ROV_MAV, "run", "--target", f"udpout:127.0.0.1:{run_port}", str(mission), "--output",
                            "motor-test", "--log", str(log), "--rerun", "off", "--heartbeat-timeout", "60"],
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines: list[str] = []
    due = threading.Event()

    def read() -> None:
        for line in run.stdout:
            lines.append(line)
            if DISARM_AT in line:
                due.set()
    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    station = mavutil.mavlink_connection(f"udpout:127.0.0.1:{station_port}", source_system=200, source_component=190)
    try:
        station.mav.heartbeat_send(6, 8, 0, 0, 0)
        station.mav.command_long_send(1, 1, mavutil.mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                                      mavutil.mavlink.MAVLINK_MSG_ID_ATTITUDE, 20000, 0, 0, 0, 0, 0)
        if not due.wait(240.0):
            raise RuntimeError("the run never reached mission t = 10 s:\n" + "".join(lines))
        station.mav.command_long_send(1, 1, mavutil.mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0, 0, 0, 0, 0, 0, 0, 0)
        ack = timed_out = neutral = None
        waiting: str | None = None      # the event whose vehicle time the next ATTITUDE gives (the link keeps order)
        deadline = time.monotonic() + 30.0
        while neutral is None and time.monotonic() < deadline:
            station.mav.heartbeat_send(6, 8, 0, 0, 0)
            m = station.recv_match(type=["COMMAND_ACK", "STATUSTEXT", "SERVO_OUTPUT_RAW", "ATTITUDE"], blocking=True,
                                   timeout=0.2)
            if m is None or m.get_srcSystem() != 1:
                continue
            kind = m.get_type()
            if kind == "ATTITUDE" and waiting == "ack":
                ack, waiting = m.time_boot_ms / 1000.0, None
            elif kind == "ATTITUDE" and waiting == "timeout":
                timed_out, waiting = m.time_boot_ms / 1000.0, None
            elif kind == "COMMAND_ACK" and m.command == mavutil.mavlink.MAV_CMD_COMPONENT_ARM_DISARM and ack is None:
                waiting = "ack"
            elif kind == "STATUSTEXT" and m.text == "Motor test timed out!":
                waiting = "timeout"
            elif kind == "SERVO_OUTPUT_RAW" and ack is not None and \
                    all(getattr(m, f"servo{i}_raw") == 1500 for i in range(1, 9)):
                neutral = m.time_usec / 1e6
        status = run.wait(timeout=60.0)
        reader.join(5.0)
    finally:
        station.close()
        stop(bridge)
        if run.poll() is None:
            stop(run)
    if ack is None or timed_out is None or neutral is None:
        raise RuntimeError(f"the station saw ack {ack}, timeout {timed_out}, neutral {neutral}")
    count, last_ms = run_log_figures(log / "mavlink.tlog")
    said = next((line.strip() for line in lines if "stopping:" in line), "(no stop line)")
    return count, last_ms, timed_out - ack, neutral - ack, status, said


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=5)
    parser.add_argument("--speedup", type=float, default=2.0)
    args = parser.parse_args()
    period_ms = 20.0 / args.speedup
    print(f"bridge --speedup {args.speedup:g} (one control period = {period_ms:.1f} wall ms), {args.trials} trials; "
          f"load average before: {open('/proc/loadavg').read().split()[0]}")
    rows = []
    for k in range(args.trials):
        with tempfile.TemporaryDirectory() as d:
            row = trial(Path(d), args.speedup)
        rows.append(row)
        count, last_ms, timeout_s, neutral_s, status, said = row
        print(f"trial {k + 1}: {count} DO_MOTOR_TEST after the first sign, the last {last_ms:.1f} wall ms after it; "
              f"'Motor test timed out!' {timeout_s:.2f} s and outputs neutral {neutral_s:.2f} s of vehicle time after "
              f"the disarm; exit {status}: {said}", flush=True)
    for name, column in (("commands after", 0), ("last command, wall ms", 1), ("timed out, vehicle s", 2),
                         ("neutral, vehicle s", 3)):
        values = [row[column] for row in rows]
        print(f"{name}: min {min(values):.2f}, median {float(np.median(values)):.2f}, max {max(values):.2f}")
    print(f"load average after: {open('/proc/loadavg').read().split()[0]}")


if __name__ == "__main__":
    main()
