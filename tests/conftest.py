"""Shared fixtures: the shipped vehicle, random states, the repository's paths."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rov_mav.model.vehicle import load_vehicle

ROOT = Path(__file__).resolve().parents[1]
MISSIONS = ROOT / "missions"


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
