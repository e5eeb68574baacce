"""Shared fixtures: the shipped vehicle, random states, the repository's paths; and the `process` marker.

A test that starts a process (any subprocess: a runner, a bridge, MAVProxy, a browser; a multiprocessing worker) or
the bridge in-process (a real-time loop on real sockets) is marked `process`; `make test-fast` runs the others. The
marks are held to what the tests do: an unmarked test that starts either fails, saying so. A session that may run
`process` tests first compiles every kernel once (`compile_kernels`).
"""

from __future__ import annotations

import multiprocessing.process
import subprocess
import sys
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
    if not hasattr(config, "workerinput") and not config.option.collectonly \
            and "not process" not in (config.option.markexpr or ""):
        compile_kernels()


def pytest_collection_modifyitems(config, items):
    """The tests that start a process first, the rest after them in their order: on two workers handed tests a
    couple at a time in this order (`make test`'s --maxschedchunk 2), the many short tests fill in behind the long
    end-to-end runs, instead of one worker left with runs queued ending the session alone."""
    items.sort(key=lambda item: item.get_closest_marker(PROCESS) is None)


# What a run compiles before it takes the vehicle (`flight.run.runner.warm_up`), as a fresh interpreter's program;
# `own` says whether it flies on its own estimator (`--estimator model`). tests/test_warm_up.py holds it to that.
RUN_WARM_UP = """
from rov_mav.control.controller import Controller, load_settings
from rov_mav.flight.thrusters.actuation import Actuation
from rov_mav.flight.run.runner import warm_up
from rov_mav.mission.missions import load_mission
from rov_mav.model.vehicle import load_vehicle
from rov_mav.shipped import resolve
vehicle = load_vehicle()
warm_up(load_mission(resolve("mission", "square")), Controller(vehicle, load_settings("fuzzy", None)),
        Actuation(vehicle, 40.0), 0.02, 0.2, own_estimate={own})
"""

# Compiles every compiled kernel into Numba's on-disk cache, in two processes side by side: the run's (the laws, the
# prediction, the run's own estimator) and the offline closed loop's (a second of `rov-mav simulate`). Cached, each
# takes a second or two.
KERNEL_WARM_UPS = (
    [sys.executable, "-c", RUN_WARM_UP.format(own=True)],
    [str(Path(sys.executable).with_name("rov-mav")), "simulate", str(MISSIONS / "line.yaml"), "--duration", "1",
     "--rerun", "off"],
)


def compile_kernels() -> None:
    """Once per session, before any test (and before pytest-xdist's workers start): on a fresh checkout the kernels'
    first compilation takes about a minute of CPU, and without this every worker and every runner process a test
    starts would compile them at once, each a run taking the vehicle with its thrusters held meanwhile."""
    procs = [subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, cwd=ROOT)
             for argv in KERNEL_WARM_UPS]
    for argv, proc in zip(KERNEL_WARM_UPS, procs):
        _, err = proc.communicate(timeout=600)
        if proc.returncode != 0:
            raise pytest.UsageError(f"compiling the kernels failed ({' '.join(argv[:3])}...): {err.strip()}")


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
