"""Test support for the bridge tests: free ports, the bridge in a thread or a subprocess, a pymavlink ground station,
a console program driven on stdin (MAVProxy), and the servo outputs as a station reads them."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

os.environ["MAVLINK20"] = "1"
from pymavlink import mavutil  # noqa: E402

mavutil.set_dialect("ardupilotmega")   # MAVLink 2 even if another test imported pymavlink first

ROV_MAV = str(Path(sys.executable).with_name("rov-mav"))
WAIT = 20.0            # s of wall time allowed for anything that should take a fraction of it
RETRY = 1.0            # s of wall time before a request is sent again
SPEEDUP = 10.0         # a bridge alone (no runner beside it) holds 10x on a loaded 2-core machine


def free_port(kind: int = socket.SOCK_DGRAM) -> int:
    """A port on 127.0.0.1 that nothing is bound to right now (UDP by default)."""
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class BridgeThread:
    """The bridge in-process (the embedded API), on free udpin ports (`links` of them, `ports`; `port` the first, the
    same as BridgeProcess's)."""

    def __init__(self, speedup: float = 10.0, links: int = 1, **config):
        from sim_bridge.config import BridgeConfig
        from sim_bridge.server import Bridge

        self.ports = [free_port() for _ in range(links)]
        self.port = self.ports[0]
        self.speedup = speedup
        self.bridge = Bridge(BridgeConfig(endpoints=tuple(f"udpin:127.0.0.1:{p}" for p in self.ports),
                                          speedup=speedup, **config))

    def __enter__(self) -> "BridgeThread":
        self.bridge.start()
        return self

    def __exit__(self, *exc) -> None:
        self.bridge.stop()


class BridgeProcess:
    """`rov-mav sim-bridge` in a subprocess; its output goes to files in `workdir`. Stops with SIGTERM on exit."""

    def __init__(self, workdir: Path, *args: str, speedup: float = 10.0):
        self.port = free_port()
        self.args = [ROV_MAV, "sim-bridge", "--listen", f"udpin:127.0.0.1:{self.port}", "--speedup", str(speedup),
                     *args]
        self.speedup = speedup
        self.out_path = workdir / f"bridge-{self.port}.out"
        self.err_path = workdir / f"bridge-{self.port}.err"
        self.proc: subprocess.Popen | None = None

    def start(self) -> "BridgeProcess":
        with open(self.out_path, "w") as out, open(self.err_path, "w") as err:
            self.proc = subprocess.Popen(self.args, stdout=out, stderr=err, stdin=subprocess.DEVNULL)
        return self

    def __enter__(self) -> "BridgeProcess":
        return self.start()

    def stop(self) -> int:
        """SIGTERM, then wait (kill after WAIT s); the exit code."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
        try:
            return self.proc.wait(WAIT)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
            raise

    def __exit__(self, exc_type, *exc) -> None:
        code = self.stop()
        if exc_type is None:
            assert code == 0 and "sim-bridge: stopped at" in self.output, self.output

    @property
    def output(self) -> str:
        return self.out_path.read_text() + self.err_path.read_text()


class Gcs:
    """A pymavlink ground station on a bridge's udpin port (or, with transport "tcp", its tcpin port), with an
    optional background heartbeat/override pump.

    `rate` is in simulated Hz: the pump sends `rate * speedup` times per wall second, as a GCS flying a sped-up
    vehicle must."""

    def __init__(self, port: int, speedup: float = 1.0, sysid: int = 255, rate: float = 2.0,
                 transport: str = "udpout"):
        self.conn = mavutil.mavlink_connection(f"{transport}:127.0.0.1:{port}", source_system=sysid,
                                               source_component=190)
        self.speedup = speedup
        self.rate = rate
        self.heartbeats = True
        self.override: list[int] | None = None
        self.joystick: tuple[int, int, int, int] | None = None      # MANUAL_CONTROL x, y, z, r
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    # -- sending ---------------------------------------------------------------------------------------------

    def send(self, name: str, *fields) -> None:
        with self._lock:
            getattr(self.conn.mav, f"{name}_send")(*fields)

    def heartbeat(self) -> None:
        self.send("heartbeat", mavutil.mavlink.MAV_TYPE_GCS, mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)

    def rc_override(self, channels: list[int]) -> None:
        """RC_CHANNELS_OVERRIDE with these channel values (18 fields; missing ones = UINT16_MAX / 0 = ignore)."""
        values = list(channels) + [65535] * (8 - len(channels)) if len(channels) < 8 else list(channels)
        values += [0] * (18 - len(values))
        self.send("rc_channels_override", 1, 1, *values)

    def manual_control(self, x: int, y: int, z: int, r: int, target: int = 1) -> None:
        """MANUAL_CONTROL as a pilot's joystick sends it (z: 0..1000, 500 = neutral; no buttons)."""
        self.send("manual_control", target, x, y, z, r, 0)

    def request(self, send, kind: str, cond, timeout: float = WAIT):
        """`send()` until a `kind` message satisfying `cond` answers, resending every second as ground stations do.

        Whatever was already queued is dropped first: an idle ground station's socket buffer fills with telemetry
        at 10x, and the kernel then drops the answer."""
        self.drop_queued()
        deadline = time.monotonic() + timeout
        while True:
            send()
            try:
                return self.recv(kind, min(RETRY, deadline - time.monotonic()), cond)
            except AssertionError:
                if time.monotonic() + 0.01 >= deadline:
                    raise AssertionError(f"no {kind} answer within {timeout} s") from None

    def command(self, command: int, *params: float, timeout: float = WAIT):
        """COMMAND_LONG and its COMMAND_ACK."""
        p = list(params) + [0.0] * (7 - len(params))
        return self.request(lambda: self.send("command_long", 1, 1, command, 0, *p), "COMMAND_ACK",
                            lambda m: m.command == command, timeout)

    def set_param(self, name: str, value: float, ptype: int = mavutil.mavlink.MAV_PARAM_TYPE_REAL32):
        """PARAM_SET and the vehicle's echo of it (index 65535)."""
        return self.request(lambda: self.send("param_set", 1, 1, name.encode(), value, ptype), "PARAM_VALUE",
                            lambda m: m.param_id == name and m.param_index == 65535)

    def get_param(self, name: str):
        """PARAM_REQUEST_READ by name and its answer (index 65535, as a PARAM_SET's echo: ArduSub echoes the
        request's -1)."""
        return self.request(lambda: self.send("param_request_read", 1, 1, name.encode(), -1), "PARAM_VALUE",
                            lambda m: m.param_id == name)

    def set_interval(self, msg_id: int, hz: float):
        return self.command(mavutil.mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, msg_id, 1e6 / hz)

    def get_interval(self, msg_id: int):
        """MAV_CMD_GET_MESSAGE_INTERVAL's answers (MESSAGE_INTERVAL, COMMAND_ACK), in the order ArduSub sends them."""
        cmd = mavutil.mavlink.MAV_CMD_GET_MESSAGE_INTERVAL
        interval = self.request(lambda: self.send("command_long", 1, 1, cmd, 0, msg_id, 0, 0, 0, 0, 0, 0),
                                "MESSAGE_INTERVAL", lambda m: m.message_id == msg_id & 0xFFFF)
        return interval, self.recv("COMMAND_ACK", cond=lambda m: m.command == cmd)

    # -- receiving -------------------------------------------------------------------------------------------

    def recv(self, kind: str | list[str] | None, timeout: float = WAIT, cond=lambda m: True):
        """The next message of `kind` satisfying `cond` within `timeout` wall seconds, else AssertionError."""
        deadline = time.monotonic() + timeout
        kinds = [kind] if isinstance(kind, str) else kind
        while time.monotonic() < deadline:
            m = self.conn.recv_match(type=kinds, blocking=True, timeout=min(0.2, deadline - time.monotonic()))
            if m is not None and cond(m):
                return m
        raise AssertionError(f"no {kind} within {timeout} s")

    def collect(self, seconds: float, kinds: list[str] | None = None) -> list:
        """Every message (of `kinds`) received during `seconds` of wall time."""
        out = []
        deadline = time.monotonic() + seconds
        while (left := deadline - time.monotonic()) > 0:
            m = self.conn.recv_match(type=kinds, blocking=True, timeout=min(0.2, left))
            if m is not None:
                out.append(m)
        return out

    def connect(self, timeout: float = WAIT):
        """Send heartbeats until the vehicle's HEARTBEAT arrives; returns it."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            self.heartbeat()
            m = self.conn.recv_match(type="HEARTBEAT", blocking=True, timeout=0.3)
            if m is not None and m.get_srcSystem() == 1:
                return m
        raise AssertionError("the bridge never sent a HEARTBEAT")

    def sim_time(self) -> float:
        """The vehicle's simulated time (s) from its next ATTITUDE."""
        return self.recv("ATTITUDE").time_boot_ms / 1000.0

    def drop_queued(self) -> list:
        """Drop (and return) every message already received and not yet read."""
        dropped = []
        while (m := self.conn.recv_match(blocking=False)) is not None:
            dropped.append(m)
        return dropped

    def sim_time_now(self) -> float:
        """The vehicle's simulated time (s) now: the newest ATTITUDE after dropping everything already queued."""
        times = [m.time_boot_ms / 1000.0 for m in self.drop_queued() if m.get_type() == "ATTITUDE"]
        return times[-1] if times else self.sim_time()

    # -- background pump -------------------------------------------------------------------------------------

    def start_pump(self) -> None:
        """Send heartbeats (if `heartbeats`), `override` and `joystick` (if set) at `rate` simulated Hz until
        closed."""
        self._thread = threading.Thread(target=self._pump, daemon=True)
        self._thread.start()

    def _pump(self) -> None:
        period = 1.0 / (self.rate * self.speedup)
        while not self._stop.wait(period):
            if self.heartbeats:
                self.heartbeat()
            if self.override is not None:
                self.rc_override(self.override)
            if self.joystick is not None:
                self.manual_control(*self.joystick)

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(WAIT)
        self.conn.close()


MAVPROXY = str(Path(sys.executable).with_name("mavproxy.py"))


class Console:
    """A console program with its stdin piped and its output in a file we poll."""

    def __init__(self, args: list[str], log: Path, cwd: Path):
        self.log = log
        with open(log, "w") as out:
            self.proc = subprocess.Popen(args, stdin=subprocess.PIPE, stdout=out, stderr=subprocess.STDOUT,
                                         cwd=cwd, text=True)
        self.seen = 0

    def expect(self, text: str, timeout: float = WAIT) -> None:
        """Wait for `text` in the output after what earlier expectations matched."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            output = self.log.read_text()
            at = output.find(text, self.seen)
            if at >= 0:
                self.seen = at + len(text)
                return
            assert self.proc.poll() is None, f"exited early:\n{output}"
            time.sleep(0.1)
        raise AssertionError(f"no {text!r} within {timeout} s in:\n{self.log.read_text()}")

    def poll(self, line: str, text: str, timeout: float = WAIT) -> None:
        """Send `line` every second until `text` appears."""
        deadline = time.monotonic() + timeout
        while True:
            self.send(line)
            try:
                return self.expect(text, 1.0)
            except AssertionError:
                if time.monotonic() > deadline:
                    raise

    def send(self, line: str) -> None:
        self.proc.stdin.write(line + "\n")
        self.proc.stdin.flush()

    def close(self, command: str) -> None:
        """Ask the program to quit with `command`, kill it if it has not within a few seconds."""
        if self.proc.poll() is None:
            try:
                self.send(command)
                self.proc.stdin.close()
                self.proc.wait(5)
            except (OSError, subprocess.TimeoutExpired):
                self.proc.kill()
                self.proc.wait()


def servo(m) -> list[int]:
    return [getattr(m, f"servo{i}_raw") for i in range(1, 9)]


def wait_servo(gcs: Gcs, cond, timeout: float = WAIT):
    return gcs.recv("SERVO_OUTPUT_RAW", timeout, lambda m: cond(servo(m)))


def use_passthrough(gcs: Gcs) -> None:
    for n in range(1, 9):
        assert gcs.set_param(f"SERVO{n}_FUNCTION", 50 + n, mavutil.mavlink.MAV_PARAM_TYPE_INT16).param_value == 50 + n
