"""Test support for `rov-mav run`: the runner as a subprocess, short missions, and checks of the vehicle's state
made by an independent pymavlink client (a sysid that is not the GCS sysid, so it neither drives nor masks)."""

from __future__ import annotations

import signal
import subprocess
import threading
import time
from pathlib import Path

from bridge_helpers import ROV_MAV, WAIT, BridgeProcess, Gcs, free_port  # noqa: F401 -- re-exported

RUN_WAIT = 180.0        # wall s for a whole run (the square at --speedup 5 takes ~20 s)
CHECKER_SYSID = 200
SPEEDUP = 5.0           # a run's loop at 50 Hz of vehicle time is 50 x SPEEDUP ticks a wall second, ~2 ms of CPU each:
                        # at 10x that is a core, and beside the bridge, a router and a station on 2 cores the runner
                        # was starved (31.8 Hz of 50) until the vehicle tipped past max_tilt; at 5x half a core


def short_mission(directory: Path, goto_x: float = 4.0, hold: float = 5.0, depth: float = 1.0,
                  limits: str = "") -> Path:
    """A mission of 4 / 0.2 + 2 + hold s (25 s by default) starting at (0, 0, depth), with the square's
    disturbance, written to `directory`."""
    path = directory / "short.yaml"
    path.write_text(f"""name: short
start: {{position: [0.0, 0.0, {depth}], heading: 0.0}}
path:
  - {{goto: [{goto_x}, 0.0, {depth}], speed: 0.2}}
  - {{hold: {hold}, heading: 90 deg}}
environment:
  disturbance: [-1.0, 1.0, 2.0, 0.1, 0.1, 0.0]
{limits}
""")
    return path


class RunnerProcess:
    """`rov-mav run ARGS` in a subprocess; its output (stdout and stderr) is collected line by line. Without a
    `--rerun` among ARGS the run records no telemetry (`--rerun off`): Rerun's own tests stream and save runs, and a
    recording at --speedup 10 would take a core from the loop the other tests measure."""

    def __init__(self, *args: str):
        self.args = [ROV_MAV, "run", *args, *(() if "--rerun" in args else ("--rerun", "off"))]
        self.lines: list[str] = []
        self.proc: subprocess.Popen | None = None
        self._changed = threading.Condition()
        self._eof = False

    def __enter__(self) -> "RunnerProcess":
        self.proc = subprocess.Popen(self.args, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                     stdin=subprocess.DEVNULL, text=True, bufsize=1)
        threading.Thread(target=self._read, daemon=True).start()
        return self

    def _read(self) -> None:
        for line in self.proc.stdout:
            with self._changed:
                self.lines.append(line.rstrip("\n"))
                self._changed.notify_all()
        with self._changed:
            self._eof = True
            self._changed.notify_all()

    def wait_for(self, text: str, timeout: float = RUN_WAIT) -> str:
        """The first line containing `text`, once printed (AssertionError with the output on timeout or exit)."""
        deadline = time.monotonic() + timeout
        with self._changed:
            while not (found := [line for line in self.lines if text in line]):
                if self._eof or time.monotonic() > deadline:
                    raise AssertionError(f"runner never printed {text!r}:\n" + "\n".join(self.lines))
                self._changed.wait(0.2)
            return found[0]

    def signal(self, signum: int) -> None:
        self.proc.send_signal(signum)

    def wait(self, timeout: float = RUN_WAIT) -> int:
        try:
            code = self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
            raise AssertionError(f"runner still running after {timeout} s:\n{self.output}") from None
        with self._changed:
            self._changed.wait_for(lambda: self._eof, WAIT)     # the reader has taken the last lines
        return code

    @property
    def output(self) -> str:
        with self._changed:
            return "\n".join(self.lines)

    def __exit__(self, *exc) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGKILL)
        self.proc.wait()


def runner_against(bridge, mission, *args: str) -> RunnerProcess:
    """`rov-mav run MISSION ARGS` against a bridge process's port (a long heartbeat wait: the bridge may still boot)."""
    return RunnerProcess("--target", f"udpout:127.0.0.1:{bridge.port}", str(mission), "--heartbeat-timeout", "60",
                         *args)


def bridge_with_checker(workdir: Path, *args: str, speedup: float = SPEEDUP) -> tuple[BridgeProcess, int]:
    """A bridge at `speedup` listening on two ports: BridgeProcess.port for the runner, the other for a checker."""
    checker_port = free_port()
    bridge = BridgeProcess(workdir, "--listen", f"udpin:127.0.0.1:{checker_port}", *args, speedup=speedup)
    return bridge, checker_port


def checker(port: int, speedup: float = SPEEDUP) -> Gcs:
    gcs = Gcs(port, speedup=speedup, sysid=CHECKER_SYSID)
    gcs.connect()
    return gcs


def fresh(gcs: Gcs, kind: str):
    """The next `kind` the vehicle (sysid 1) sent after everything already queued was dropped (other stations'
    heartbeats reach this link too: the vehicle forwards them)."""
    while gcs.conn.recv_match(blocking=False) is not None:
        pass
    return gcs.recv(kind, cond=lambda m: m.get_srcSystem() == 1)


def servo_functions(gcs: Gcs) -> list[int]:
    return [int(gcs.get_param(f"SERVO{n}_FUNCTION").param_value) for n in range(1, 9)]


def watch_run(gcs, run) -> tuple[list[str], bool]:
    """Until the runner exits: the PARAM_VALUEs the vehicle broadcast (a PARAM_SET's echo on every link) and whether
    any HEARTBEAT showed it armed."""
    written, armed = [], False
    deadline = time.monotonic() + RUN_WAIT
    while run.proc.poll() is None and time.monotonic() < deadline:
        m = gcs.conn.recv_match(type=["PARAM_VALUE", "HEARTBEAT"], blocking=True, timeout=0.2)
        if m is None or m.get_srcSystem() != 1:
            continue
        if m.get_type() == "PARAM_VALUE":
            written.append(f"{m.param_id}={m.param_value:g}")
        else:
            armed |= bool(m.base_mode & 128)
    return written, armed


def servo_functions_16(gcs) -> list[int]:
    return [int(gcs.get_param(f"SERVO{n}_FUNCTION").param_value) for n in range(1, 17)]


def servo_outputs(gcs: Gcs) -> list[int]:
    msg = fresh(gcs, "SERVO_OUTPUT_RAW")
    return [getattr(msg, f"servo{n}_raw") for n in range(1, 9)]


def armed(gcs: Gcs) -> bool:
    return bool(fresh(gcs, "HEARTBEAT").base_mode & 128)


def assert_left_safe(gcs: Gcs) -> None:
    """Disarmed, neutral on SERVO1..8, and SERVO1..8_FUNCTION back to the motors (33..40)."""
    assert not armed(gcs)
    assert servo_outputs(gcs) == [1500] * 8
    assert servo_functions(gcs) == list(range(33, 41))
