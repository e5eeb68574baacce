"""The built-in vehicle in a process of its own, for `rov-mav run` without --target.

A vehicle in a thread of the runner's process shares its interpreter lock: at --speedup 10 the two took turns, the
runner's loop fell to 16 of its 50 Hz and the vehicle rolled past 15 degrees, a failure of the lab, not of the law.
A real autopilot never waits for the ground's interpreter. In its own process the vehicle is paced by its own clock,
as a `rov-mav sim-bridge` is, and reached over the same UDP.

The child ignores the terminal's signals (Ctrl-C reaches the whole process group, and the runner's safe stop needs
its vehicle until the stop is done), ends on SIGTERM from the runner, and is sent SIGTERM by the kernel if the runner
dies outright (PR_SET_PDEATHSIG).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import multiprocessing
import signal

from sim_bridge.config import BridgeConfig
from sim_bridge.transport.link import TransportError

START_TIMEOUT = 120.0       # wall s for the child to import, load its compiled model and open its link
STOP_TIMEOUT = 10.0         # wall s for it to end on SIGTERM before it is killed
PR_SET_PDEATHSIG = 1


def _serve(config: BridgeConfig, ready) -> None:
    """The child: the bridge from `config`, announced on `ready` as ("ok", firmware) or ("error", one line); its
    clock starts when the parent says "go" (or goes away)."""
    for signum in (signal.SIGINT, signal.SIGHUP, signal.SIGQUIT):
        signal.signal(signum, signal.SIG_IGN)
    libc = ctypes.CDLL(ctypes.util.find_library("c"), use_errno=True)
    libc.prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
    from sim_bridge.server import Bridge

    try:
        bridge = Bridge(config)
        bridge.open()
    except (TransportError, ValueError) as exc:
        ready.send(("error", str(exc)))
        return
    signal.signal(signal.SIGTERM, lambda *_: bridge.request_stop())
    ready.send(("ok", bridge.params.firmware))
    try:
        ready.recv()
    except EOFError:
        return
    bridge.run()


class VehicleProcess:
    """`launch()` the bridge of `config` in a child process (it loads meanwhile), `start()` its clock (TransportError if
    it cannot start), `stop()` it."""

    def __init__(self, config: BridgeConfig):
        self.config = config
        self.firmware: str | None = None
        self._process = None
        self._pipe = None

    def launch(self) -> None:
        """Spawn the child; it imports and loads its compiled model while the caller gets ready."""
        context = multiprocessing.get_context("spawn")   # a fresh interpreter: no threads or locks inherited
        self._pipe, child = context.Pipe()
        self._process = context.Process(target=_serve, args=(self.config, child), name="built-in vehicle",
                                        daemon=True)
        self._process.start()
        child.close()

    def start(self) -> None:
        """Once the child is loaded and its link open: its clock starts now."""
        if self._process is None:
            self.launch()
        receive = self._pipe
        if not receive.poll(START_TIMEOUT):
            self.stop()
            raise TransportError(f"no answer within {START_TIMEOUT:g} s")
        try:
            status, text = receive.recv()
        except EOFError:
            self._process.join(STOP_TIMEOUT)
            code = self._process.exitcode
            self.stop()
            raise TransportError(f"it exited with status {code}") from None
        if status != "ok":
            self.stop()
            raise TransportError(text)
        self.firmware = text
        receive.send("go")

    def stop(self) -> None:
        if self._process is None:
            return
        if self._process.is_alive():
            self._process.terminate()
            self._process.join(STOP_TIMEOUT)
            if self._process.is_alive():
                self._process.kill()
        self._process.join()
        self._process = None
