"""ArduPilot's own ArduSub SITL as a child process: for the end-to-end tests and the tools that fly missions on it.

The binary is the user's (`ARDUSUB_SITL`: e.g. build/sitl/bin/ardusub in an ArduPilot tree built with `./waf
configure --board sitl && ./waf sub`, with ArduPilot's `sub-6dof.parm` next to it or named by
`ARDUSUB_SITL_DEFAULTS`). Each instance runs in its own scratch directory (it writes eeprom.bin and logs/ there)
on a free instance number (SERIAL0 on TCP 5760+10N, SERIAL1 on 5762+10N), with its parameters wiped
at boot, and is ended by its PID (with SIGKILL if it ignores SIGTERM, which a SITL stuck draining a dead client's
TCP queue can do). Extra parameters go in a second defaults file, applied after ArduPilot's.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import time
from pathlib import Path

SITL_ENV = "ARDUSUB_SITL"
DEFAULTS_ENV = "ARDUSUB_SITL_DEFAULTS"
DEFAULTS_FILE = "sub-6dof.parm"
HOME = "33.810313,-118.393867,0,185"     # ArduPilot's sub test site (lat, lon, alt m, heading deg)
BASE_PORT = 5760
INSTANCES = range(20, 60)
BOOT_WAIT = 60.0                          # wall s for SERIAL0 to open
STOP_WAIT = 5.0                           # wall s for SIGTERM before SIGKILL


class SitlError(Exception):
    """SITL cannot be found or started; the message says why in one line."""


def binary_from_environment() -> Path | None:
    """The binary `ARDUSUB_SITL` names (None when unset); SitlError when it is not an executable file."""
    path = os.environ.get(SITL_ENV)
    if not path:
        return None
    binary = Path(path).resolve()
    if not binary.is_file() or not os.access(binary, os.X_OK):
        raise SitlError(f"{SITL_ENV}={path} is not an executable file")
    return binary


def free_instance() -> int:
    """An instance number N whose SERIAL0..2 ports (5760+10N, 5762+10N, 5763+10N) are free."""
    for n in INSTANCES:
        try:
            for offset in (0, 2, 3):
                with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
                    s.bind(("127.0.0.1", BASE_PORT + 10 * n + offset))
            return n
        except OSError:
            continue
    raise SitlError("no free SITL instance number (ports 5960-6353 all taken)")


class Sitl:
    """ArduSub SITL (vectored_6dof) in `workdir`: SERIAL0 on `serial0` (default TCP `port0`), SERIAL1 on TCP
    `port1`; `params` (name -> value) are set at boot on top of the defaults file."""

    def __init__(self, binary: Path, workdir: Path, speedup: float, serial0: str | None = None,
                 params: dict[str, float] | None = None):
        self.binary = Path(binary)
        defaults = Path(os.environ.get(DEFAULTS_ENV, self.binary.with_name(DEFAULTS_FILE)))
        if not defaults.is_file():
            raise SitlError(f"no SITL defaults file {defaults} (set {DEFAULTS_ENV})")
        self.instance = free_instance()
        self.port0 = BASE_PORT + 10 * self.instance
        self.port1 = self.port0 + 2
        self.speedup = speedup
        self.workdir = Path(workdir)
        self.params = dict(params or {})
        files = str(defaults)
        if self.params:
            files += "," + str(self.workdir / "extra.parm")
        self.args = [str(self.binary), "--model", "vectored_6dof", "--defaults", files, "--home", HOME,
                     "-I", str(self.instance), "-w", "--speedup", f"{speedup:g}"]
        if serial0:
            self.args += ["--serial0", serial0]
        self.proc: subprocess.Popen | None = None

    def __enter__(self) -> "Sitl":
        self.workdir.mkdir(parents=True, exist_ok=True)
        if self.params:
            (self.workdir / "extra.parm").write_text("".join(f"{k} {v:g}\n" for k, v in self.params.items()))
        with open(self.workdir / "sitl.out", "w") as out:
            self.proc = subprocess.Popen(self.args, cwd=self.workdir, stdout=out, stderr=subprocess.STDOUT,
                                         stdin=subprocess.DEVNULL, start_new_session=True)
        return self

    def __exit__(self, *exc) -> None:
        self.stop()

    def stop(self) -> None:
        """End the process by its PID: SIGTERM, then SIGKILL if it does not go."""
        if self.proc is None or self.proc.poll() is not None:
            return
        self.proc.send_signal(signal.SIGTERM)
        try:
            self.proc.wait(STOP_WAIT)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()

    @property
    def target(self) -> str:
        return f"tcp:127.0.0.1:{self.port0}"

    def output(self) -> str:
        path = self.workdir / "sitl.out"
        return path.read_text(errors="replace") if path.exists() else ""

    def wait_for_port(self, port: int, timeout: float = BOOT_WAIT) -> None:
        """Until SITL accepts TCP connections on `port`; SitlError if it exits or never does."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
                if s.connect_ex(("127.0.0.1", port)) == 0:
                    return
            if self.proc.poll() is not None:
                raise SitlError(f"SITL exited with status {self.proc.returncode}: {self.output()[-500:]}")
            time.sleep(0.2)
        raise SitlError(f"SITL never opened port {port} within {timeout:g} s")
