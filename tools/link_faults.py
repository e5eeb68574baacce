"""Measure: a mission flown by `rov-mav run` against the built-in vehicle over a degraded link, and by a starved runner.

For every loss (default 0/10/20/30 %, each way) x delay (default 0/50/100 ms of vehicle time, each way) x prediction
(`--predict on` and `off`, side by side in the same row) it starts `rov-mav run` (--metrics) and, once the runner is up
and calling, `rov-mav sim-bridge` with --link-faults on the runner's link and a
second, clean link for a checker (so the vehicle does not drift in the mission's disturbance while the runner
starts); after the run the checker reads the vehicle's end state (armed?, SERVO_OUTPUT_RAW, SERVO1..8_FUNCTION).
Prints a markdown table: completed, exit status, RMS position error, control rate, watchdog episodes, loss measured by
the bridge, end state, and the pace the simulated vehicle kept (its achieved speedup, and slips: stalls of over a
second of wall time on a loaded machine, which the runner rightly takes for a lost link). A last row: a runner
stopped with SIGSTOP for 200 ms of every 300 ms for 15 s once armed (`--starve`), on a clean link at real time. Run:
    .venv/bin/python tools/link_faults.py [--mission missions/square.yaml] [--speedup 2] [--jitter 0ms] [--seed 0]
                                          [--losses 0,0.1,0.2,0.3] [--delays 0,50,100] [--no-starve]
                                          [--keep DIR]   # every run's and bridge's output, to look into a row
"""

from __future__ import annotations

import argparse
import json
import os
import re
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
ROV_MAV = str(Path(sys.executable).with_name("rov-mav"))
LOSSES = (0.0, 0.1, 0.2, 0.3)
DELAYS_MS = (0, 50, 100)
CHECKER_SYSID = 200         # not the GCS sysid: it neither drives the vehicle nor hides a lost link
WAIT = 30.0                 # wall s for the checker's answers
RUN_WAIT = 1800.0           # wall s for one run
STARVE_STOP, STARVE_PERIOD, STARVE_FOR = 0.2, 0.3, 15.0   # the starved runner: stopped 200 ms of every 300, 15 s


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Checker:
    """A pymavlink station on the bridge's clean link."""

    def __init__(self, port: int):
        self.conn = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=CHECKER_SYSID,
                                               source_component=190, dialect="ardupilotmega")

    def request(self, send, kind: str, cond):
        deadline = time.monotonic() + WAIT
        while time.monotonic() < deadline:
            send()
            resend = time.monotonic() + 1.0
            while time.monotonic() < resend:
                msg = self.conn.recv_match(type=kind, blocking=True, timeout=0.2)
                if msg is not None and cond(msg):
                    return msg
        raise RuntimeError(f"the vehicle did not answer with {kind} on the clean link")

    def fresh(self, kind: str):
        while self.conn.recv_match(blocking=False) is not None:
            pass
        mav = mavutil.mavlink
        return self.request(lambda: self.conn.mav.heartbeat_send(mav.MAV_TYPE_GCS, mav.MAV_AUTOPILOT_INVALID, 0, 0,
                                                                  mav.MAV_STATE_ACTIVE), kind, lambda m: True)

    def param(self, name: str) -> int:
        msg = self.request(lambda: self.conn.mav.param_request_read_send(1, 1, name.encode(), -1), "PARAM_VALUE",
                           lambda m: m.param_id == name)
        return int(msg.param_value)

    def end_state(self) -> str:
        armed = bool(self.fresh("HEARTBEAT").base_mode & mavutil.mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
        servo = self.fresh("SERVO_OUTPUT_RAW")
        outputs = [getattr(servo, f"servo{n}_raw") for n in range(1, 9)]
        functions = [self.param(f"SERVO{n}_FUNCTION") for n in range(1, 9)]
        safe = not armed and outputs == [1500] * 8 and functions == list(range(33, 41))
        if safe:
            return "safe (disarmed, neutral, motors)"
        return ", ".join(filter(None, ["ARMED" if armed else "disarmed",
                                       "neutral" if outputs == [1500] * 8 else f"outputs {outputs}",
                                       "motors" if functions == list(range(33, 41)) else f"functions {functions}"]))

    def close(self) -> None:
        self.conn.close()


def runner_calling(port: int) -> None:
    """Until the runner sends its first hello to `port` (it is then past its own start)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", port))
        sock.settimeout(WAIT * 4)
        sock.recvfrom(65535)


def stop(proc: subprocess.Popen) -> str:
    """SIGTERM (SIGKILL if it lingers); everything it printed."""
    proc.terminate()
    try:
        return proc.communicate(timeout=WAIT)[0]
    except subprocess.TimeoutExpired:
        proc.kill()
        return proc.communicate()[0]


def starve(pid: int, started: threading.Event, done: threading.Event) -> None:
    """Once `started`: SIGSTOP the runner for STARVE_STOP of every STARVE_PERIOD wall s for STARVE_FOR s."""
    if not started.wait(RUN_WAIT):
        return
    until = time.monotonic() + STARVE_FOR
    while time.monotonic() < until and not done.is_set():
        try:
            os.kill(pid, signal.SIGSTOP)
            time.sleep(STARVE_STOP)
            os.kill(pid, signal.SIGCONT)
        except ProcessLookupError:
            return
        time.sleep(STARVE_PERIOD - STARVE_STOP)


def fly(mission: Path, loss: float, delay_ms: int, predict: str, args, folder: Path, starved: bool = False) -> dict:
    """One run at this loss, delay and prediction (a starved runner at real time when `starved`): its figures."""
    port, clean = free_port(), free_port()
    faults = f"loss={loss:g},delay={delay_ms}ms,link=0" + (f",jitter={args.jitter}" if args.jitter else "")
    name = f"{loss:g}-{delay_ms}-{predict}" + ("-starved" if starved else "")
    metrics_path = folder / f"metrics-{name}.json"
    runner = subprocess.Popen([ROV_MAV, "run", "--target", f"udpout:127.0.0.1:{port}", str(mission), "--metrics",
                               str(metrics_path), "--rerun", "off", "--heartbeat-timeout", "60", "--predict", predict],
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    bridge = None
    armed, done = threading.Event(), threading.Event()
    lines: list[str] = []
    try:
        runner_calling(port)
        bridge = subprocess.Popen([ROV_MAV, "sim-bridge", "--listen", f"udpin:127.0.0.1:{port}", "--listen",
                                   f"udpin:127.0.0.1:{clean}", "--speedup", "1" if starved else str(args.speedup),
                                   "--environment", str(mission), "--start-depth", str(args.start_depth), "--seed",
                                   str(args.seed), "--link-faults", faults],
                                  stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        stopper = threading.Thread(target=starve, args=(runner.pid, armed, done), daemon=True) if starved else None
        if stopper is not None:
            stopper.start()
        for line in runner.stdout:
            lines.append(line)
            if "armed in MANUAL" in line:
                armed.set()
        runner.wait(RUN_WAIT)
        done.set()
        output = "".join(lines)
        checker = Checker(clean)
        try:
            end = checker.end_state()
        finally:
            checker.close()
    finally:
        done.set()
        armed.set()
        if runner.poll() is None:
            output = "".join(lines) + stop(runner)
        bridge_out = stop(bridge) if bridge is not None else ""
    metrics = json.loads(metrics_path.read_text()) if metrics_path.exists() else {}
    if args.keep is not None:
        args.keep.mkdir(parents=True, exist_ok=True)
        (args.keep / f"run-{name}.txt").write_text(output)
        (args.keep / f"bridge-{name}.txt").write_text(bridge_out)
    stale = re.search(r"telemetry went stale (\d+) time", output)
    measured = re.search(r"to the vehicle (\d+) sent, (\d+) lost .*; from it (\d+) sent, (\d+) lost", bridge_out)
    up_sent, up_lost, down_sent, down_lost = map(int, measured.groups()) if measured else (0, 0, 0, 0)
    reason = re.search(r"stopping: (.*)", output)
    pace = re.search(r"\(speedup ([\d.]+), (\d+) slips\)", bridge_out)
    round_trip = re.search(r"delays: round trip ([\d.]+) ms", output)
    stalls = re.search(r"this process stalled (\d+) time", output)
    return {
        "loss": loss, "delay_ms": delay_ms, "code": runner.returncode,
        "completed": bool(metrics.get("completed", False)),
        "reason": reason.group(1) if reason else output.strip().splitlines()[-1] if output.strip() else "",
        "rms_cm": 100 * metrics["rms_position_error_m"] if "rms_position_error_m" in metrics else float("nan"),
        "max_cm": 100 * metrics["max_position_error_m"] if "max_position_error_m" in metrics else float("nan"),
        "round_trip_ms": float(round_trip.group(1)) if round_trip else float("nan"),
        "stalls": int(stalls.group(1)) if stalls else 0,
        "rate_hz": metrics.get("loop", {}).get("control_rate_hz", float("nan")),
        "stale": int(stale.group(1)) if stale else 0,
        "lost_up": up_lost / max(up_sent, 1), "lost_down": down_lost / max(down_sent, 1),
        "incomplete_stop": "safe stop NOT complete" in output,
        "pace": f"{float(pace.group(1)):.2f}x, {pace.group(2)} slips" if pace else "?",
        "end": end,
    }


def _cell(r: dict) -> str:
    """One prediction's figures in a row: completed (or why not), exit, RMS / max error."""
    done = "yes" if r["completed"] else f"no: {r['reason']}"
    return f"{done} | {r['code']} | {r['rms_cm']:.2f} / {r['max_cm']:.1f} cm"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mission", type=Path, default=ROOT / "missions" / "square.yaml")
    parser.add_argument("--speedup", type=float, default=2.0,
                        help="the vehicle's speedup (default 2: on a loaded machine, a starved runner at 5x or more "
                             "trips the vehicle's 3 s pilot-input failsafe)")
    parser.add_argument("--start-depth", type=float, default=1.0, help="the vehicle's depth at boot, m")
    parser.add_argument("--jitter", default="", help="also jitter each delay by this much, e.g. 10ms")
    parser.add_argument("--losses", default=",".join(f"{v:g}" for v in LOSSES), help="loss each way, e.g. 0,0.3")
    parser.add_argument("--delays", default=",".join(str(v) for v in DELAYS_MS), help="delay each way, ms")
    parser.add_argument("--no-starve", action="store_true", help="leave out the starved runner's row")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--keep", type=Path, help="write every run's and bridge's output to this folder")
    args = parser.parse_args()
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))      # unwind: the runner and the bridge are stopped
    print(f"mission {args.mission.name}, bridge --speedup {args.speedup:g}, loss and delay applied each way"
          f"{', jitter ' + args.jitter if args.jitter else ''}, seed {args.seed}; load average before: "
          f"{os.getloadavg()[0]:.1f}", flush=True)
    print("| loss | delay | predict on: completed | exit | RMS / max error | predict off: completed | exit | "
          "RMS / max error | round trip | control rate | watchdog episodes | measured loss (to / from the vehicle) | "
          "end state (on) | vehicle's pace (on) |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
          flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        for loss in (float(v) for v in args.losses.split(",")):
            for delay in (int(v) for v in args.delays.split(",")):
                on, off = (fly(args.mission, loss, delay, p, args, Path(tmp)) for p in ("on", "off"))
                end = on["end"] + (" — safe stop NOT complete" if on["incomplete_stop"] else "")
                print(f"| {loss:.0%} | {delay} ms | {_cell(on)} | {_cell(off)} | {on['round_trip_ms']:.0f} ms | "
                      f"{on['rate_hz']:.1f} Hz | {on['stale']} | {on['lost_up']:.1%} / {on['lost_down']:.1%} | "
                      f"{end} | {on['pace']} |", flush=True)
        if not args.no_starve:
            on, off = (fly(args.mission, 0.0, 0, p, args, Path(tmp), starved=True) for p in ("on", "off"))
            print(f"| starved: SIGSTOP {STARVE_STOP * 1e3:.0f} of every {STARVE_PERIOD * 1e3:.0f} ms for "
                  f"{STARVE_FOR:g} s, real time | 0 ms | {_cell(on)} | {_cell(off)} | {on['round_trip_ms']:.0f} ms | "
                  f"{on['rate_hz']:.1f} Hz | {on['stale']} | - | {on['end']} | {on['pace']} |", flush=True)
    print(f"load average after: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
