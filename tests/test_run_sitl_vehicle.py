"""The runner on a vehicle whose thrusters follow a quadratic law with a dead band (ArduPilot SITL's submarine,
vehicles/ardusub_sitl.yaml), played by the built-in vehicle: the PWMs it sends go through that law end to end, and
its pretension keeps every thruster outside the dead band while it holds station."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from pymavlink import mavutil
from run_helpers import BridgeProcess, RunnerProcess, short_mission

pytestmark = pytest.mark.process      # starts a process or the bridge (tests/conftest.py)

SITL_VEHICLE = str(Path(__file__).resolve().parents[1] / "vehicles" / "ardusub_sitl.yaml")
SPEEDUP = 5.0


def _hold_outputs(log: Path) -> np.ndarray:
    """SERVO_OUTPUT_RAW (N, 8) reported while the run held its outputs on passthrough (non-neutral reports)."""
    tlog = mavutil.mavlink_connection(str(log / "mavlink.tlog"))
    rows = []
    while (msg := tlog.recv_match(type="SERVO_OUTPUT_RAW")) is not None:
        rows.append([getattr(msg, f"servo{i}_raw") for i in range(1, 9)])
    rows = np.array(rows, dtype=float)
    return rows[np.any(rows != 1500, axis=1)]


def test_a_quadratic_thruster_vehicle_is_flown_with_its_own_law_outside_the_dead_band(tmp_path):
    mission = short_mission(tmp_path, goto_x=2.0, hold=6.0)
    metrics = tmp_path / "metrics.json"
    with BridgeProcess(tmp_path, "--vehicle", SITL_VEHICLE, "--start-depth", "1", speedup=SPEEDUP) as bridge, \
            RunnerProcess("--target", f"udpout:127.0.0.1:{bridge.port}", str(mission), "--vehicle", SITL_VEHICLE,
                          "--rerun", "off", "--metrics", str(metrics), "--log", str(tmp_path / "log"),
                          "--heartbeat-timeout", "60") as run:
        assert run.wait() == 0, run.output
    result = json.loads(metrics.read_text())
    # The model is the plant, thrust law included (still water): the law meets it almost exactly.
    assert result["completed"] and result["rms_position_error_m"] < 0.03, run.output
    outputs = _hold_outputs(tmp_path / "log")
    assert len(outputs) > 20
    outside = np.all(np.abs(outputs - 1500) > 25, axis=1)          # SITL's dead band is 1475..1525 us
    assert outside.mean() > 0.9, outputs[~outside][:5]
