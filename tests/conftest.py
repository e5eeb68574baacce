"""Shared fixtures: the shipped vehicle, random states, the repository's paths; and the `process` marker.

A test that starts a process (any subprocess: a runner, a bridge, MAVProxy, a browser; a multiprocessing worker) or
the bridge in-process (a real-time loop on real sockets) is marked `process`; `make test-fast` runs the others. The
marks are held to what the tests do: an unmarked test that starts either fails, saying so.
"""

from __future__ import annotations

import multiprocessing.process
import subprocess
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

from rov_mav.model.vehicle import load_vehicle

ROOT = Path(__file__).resolve().parents[1]
MISSIONS = ROOT / "missions"


PROCESS = "process"


class StartsAProcess(RuntimeError):
    """An unmarked test started a process or a bridge."""


def pytest_configure(config):
    config.addinivalue_line("markers", f"{PROCESS}: starts a process or the bridge (real sockets, wall-clock pacing); "
                                       "`make test-fast` leaves these out")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_setup(item):
    with _guarded(item):
        yield


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_call(item):
    with _guarded(item):
        yield


@contextmanager
def _guarded(item):
    """Around an unmarked test's setup and call: starting a subprocess, a multiprocessing worker or the bridge raises
    StartsAProcess, naming the test."""
    if item.get_closest_marker(PROCESS) is not None:
        yield
        return
    from sim_bridge.server import Bridge

    def refuse(*args, **kwargs):
        raise StartsAProcess(f"{item.nodeid} starts a process or the bridge: mark it @pytest.mark.{PROCESS}")

    with pytest.MonkeyPatch.context() as patch:
        for owner, name in ((subprocess.Popen, "__init__"), (multiprocessing.process.BaseProcess, "start"),
                            (Bridge, "start")):
            patch.setattr(owner, name, refuse)
        yield


@pytest.fixture(autouse=True)
def _no_viewer_windows(monkeypatch):
    """Runs started by tests record Rerun telemetry to a file instead of opening a viewer window."""
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)


@pytest.fixture(scope="session")
def vehicle():
    return load_vehicle()


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


def random_states(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """n random poses (tilt within Assumption 1's range) and body velocities."""
    eta = np.concatenate([rng.uniform(-5, 5, (n, 3)), rng.uniform(-1.2, 1.2, (n, 2)),
                          rng.uniform(-np.pi, np.pi, (n, 1))], axis=1)
    nu = rng.uniform(-1.0, 1.0, (n, 6))
    return eta, nu
