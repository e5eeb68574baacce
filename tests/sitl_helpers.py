"""ArduPilot's own ArduSub SITL for end-to-end tests, found through ARDUSUB_SITL (the binary; its defaults file
sub-6dof.parm next to it, or ARDUSUB_SITL_DEFAULTS). Each instance gets a scratch directory, a free instance number
and is ended by its PID (with SIGKILL if it ignores SIGTERM, which a stuck SITL can)."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import time
from pathlib import Path

import pytest

SITL_ENV = "ARDUSUB_SITL"
SPEEDUP = 4.0                 # a 2-core machine shared with the runner holds this
BOOT_WAIT = 60.0              # wall s for the first heartbeat
HOME = "33.810313,-118.393867,0,185"


def sitl_binary() -> Path:
    """The SITL binary, or skip with the reason (CI sets ARDUSUB_SITL, so it runs these)."""
    path = os.environ.get(SITL_ENV)
    if not path:
        pytest.skip(f"{SITL_ENV} is not set: point it at an ArduSub SITL binary (e.g. ../shared/sitl/ardusub) to run "
                    "the tests against real ArduSub")
    binary = Path(path).resolve()
    if not os.access(binary, os.X_OK):
        pytest.fail(f"{SITL_ENV}={path} is not an executable file")
    return binary


def _free_instance() -> int:
    """An instance number N whose SERIAL0..2 ports (5760+10N, 5762+10N, 5763+10N) are free."""
    for n in range(20, 60):
        try:
            for offset in (0, 2, 3):
                with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
                    s.bind(("127.0.0.1", 5760 + 10 * n + offset))
            return n
        except OSError:
            continue
    raise RuntimeError("no free SITL instance number")


class Sitl:
    """ArduSub SITL (vectored_6dof) in `workdir`: SERIAL0 on `serial0` (default TCP 5760+10N), SERIAL1 on TCP
    `port1`. Wiped parameters at every boot."""

    def __init__(self, workdir: Path, serial0: str | None = None, speedup: float = SPEEDUP):
        self.binary = sitl_binary()
        defaults = Path(os.environ.get("ARDUSUB_SITL_DEFAULTS", self.binary.with_name("sub-6dof.parm")))
        self.instance = _free_instance()
        self.port0 = 5760 + 10 * self.instance
        self.port1 = self.port0 + 2
        self.speedup = speedup
        self.workdir = workdir
        self.args = [str(self.binary), "--model", "vectored_6dof", "--defaults", str(defaults), "--home", HOME,
                     "-I", str(self.instance), "-w", "--speedup", f"{speedup:g}"]
        if serial0:
            self.args += ["--serial0", serial0]
        self.proc: subprocess.Popen | None = None

    def __enter__(self) -> "Sitl":
        self.workdir.mkdir(parents=True, exist_ok=True)
        with open(self.workdir / "sitl.out", "w") as out:
            self.proc = subprocess.Popen(self.args, cwd=self.workdir, stdout=out, stderr=subprocess.STDOUT,
                                         stdin=subprocess.DEVNULL, start_new_session=True)
        return self

    def __exit__(self, *exc) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()

    @property
    def target(self) -> str:
        return f"tcp:127.0.0.1:{self.port0}"

    def wait_for_port(self, port: int) -> None:
        deadline = time.monotonic() + BOOT_WAIT
        while time.monotonic() < deadline:
            with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
                if s.connect_ex(("127.0.0.1", port)) == 0:
                    return
            assert self.proc.poll() is None, (self.workdir / "sitl.out").read_text()
            time.sleep(0.2)
        raise AssertionError(f"SITL never opened port {port}")


class Checker:
    """An independent pymavlink client on a SITL TCP port, as sysid 200 (neither drives nor masks a GCS)."""

    def __init__(self, port: int):
        from pymavlink import mavutil

        self.mavlink = mavutil.mavlink
        self.conn = mavutil.mavlink_connection(f"tcp:127.0.0.1:{port}", source_system=200, source_component=190,
                                               autoreconnect=True)
        self.conn.wait_heartbeat(timeout=BOOT_WAIT)

    def fresh(self, kind: str, timeout: float = 10.0):
        """The next `kind` after everything queued was dropped (asked for once a second with REQUEST_MESSAGE)."""
        while self.conn.recv_match(blocking=False) is not None:
            pass
        deadline = time.monotonic() + timeout
        msg_id = getattr(self.mavlink, f"MAVLINK_MSG_ID_{kind}")
        while time.monotonic() < deadline:
            if kind != "HEARTBEAT":
                self.conn.mav.command_long_send(1, 1, self.mavlink.MAV_CMD_REQUEST_MESSAGE, 0, msg_id,
                                                0, 0, 0, 0, 0, 0)
            msg = self.conn.recv_match(type=kind, blocking=True, timeout=1.0)
            if msg is not None and msg.get_srcSystem() == 1:
                return msg
        raise AssertionError(f"no {kind} from SITL within {timeout} s")

    def param(self, name: str) -> float:
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline:
            self.conn.mav.param_request_read_send(1, 1, name.encode(), -1)
            msg = self.conn.recv_match(type="PARAM_VALUE", blocking=True, timeout=1.0)
            if msg is not None and msg.param_id == name:
                return msg.param_value
        raise AssertionError(f"SITL did not report {name}")

    def achieved_speedup(self, wall: float = 3.0) -> float:
        """Simulated seconds per wall second over `wall` s, from SYSTEM_TIME.time_boot_ms."""
        first = self.fresh("SYSTEM_TIME")
        t0 = time.monotonic()
        time.sleep(wall)
        last = self.fresh("SYSTEM_TIME")
        return (last.time_boot_ms - first.time_boot_ms) / 1e3 / (time.monotonic() - t0)

    def wait_for_position(self, timeout: float) -> None:
        """Until the EKF has a position (LOCAL_POSITION_NED answers)."""
        self.fresh("LOCAL_POSITION_NED", timeout)

    def armed(self) -> bool:
        return bool(self.fresh("HEARTBEAT").base_mode & self.mavlink.MAV_MODE_FLAG_SAFETY_ARMED)

    def servo_outputs(self) -> list[int]:
        msg = self.fresh("SERVO_OUTPUT_RAW")
        return [getattr(msg, f"servo{n}_raw") for n in range(1, 9)]

    def servo_functions(self) -> list[int]:
        return [int(self.param(f"SERVO{n}_FUNCTION")) for n in range(1, 9)]

    def assert_left_safe(self) -> None:
        assert not self.armed()
        assert self.servo_outputs() == [1500] * 8
        assert self.servo_functions() == list(range(33, 41))

    def close(self) -> None:
        self.conn.close()
