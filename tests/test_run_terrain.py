"""Altitude legs flown by `rov-mav run` on the built-in vehicle over a bottom it sees through its echo sounder: the
depth made online from the soundings (`rov_mav.mission.terrain`), held against the true bottom the vehicle reports
beside its truth; a dropout held without a move toward the bottom; a bottom rising faster than the run climbs;
a bottom lost for good stops the run."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from plan_helpers import EARTH_MEAN_RADIUS, HOME, waypoint, write_plan
from run_helpers import RunnerProcess

from rov_mav.review.logdir import read_run_folder

pytestmark = pytest.mark.process
SPEEDUP = 5.0
IDEAL_WITH = {"preset": "ideal"}


def transect(tmp_path: Path, seafloor: dict, sounder: dict, length: float = 10.0, speed: float = 0.2,
             start_depth: float = 7.0) -> Path:
    path = tmp_path / "transect.yaml"
    path.write_text(yaml.safe_dump({
        "name": "test_transect", "start": {"position": [0.0, 0.0, start_depth], "heading": 0.0},
        "path": [{"hold": 4.0, "altitude": 1.0}, {"goto": [length, 0.0], "altitude": 1.0, "speed": speed},
                 {"hold": 2.0, "altitude": 1.0}],
        "environment": {"seafloor": seafloor, "navigation": {"preset": "ideal", "echo_sounder": sounder}},
        "limits": {"max_depth": 12.0}}))
    return path


def fly(tmp_path: Path, mission: Path) -> tuple[int, str, dict, dict]:
    log, metrics = tmp_path / "log", tmp_path / "metrics.json"
    with RunnerProcess(str(mission), "--speedup", str(SPEEDUP), "--log", str(log), "--metrics", str(metrics)) as run:
        code = run.wait()
    ticks = read_run_folder(log).ticks
    return code, run.output, ticks, json.loads(metrics.read_text()) if metrics.exists() else {}


def test_a_slope_is_climbed_at_the_altitude_and_a_dropout_is_held_without_a_move_toward_the_bottom(tmp_path):
    """1 m above a 10 % slope at 0.2 m/s with a Ping-like sounder that loses the bottom for 3 s (vehicle time 40-43 s
    since the bridge started: on the slope): the true height within 5 cm RMS of 1 m; during the dropout and the
    estimate's grace after it, the depth reference never goes deeper."""
    sounder = {"preset": "ping", "dropout_probability": 0.0, "false_lock_probability": 0.0, "outages": [[40.0, 3.0]]}
    code, output, ticks, metrics = fly(tmp_path, transect(tmp_path, {"depth": 8.0, "slope": 0.1}, sounder))
    assert code == 0 and metrics["completed"], output
    on_leg = (ticks["t"] > 4.0) & np.isfinite(ticks["height_true"])
    error = ticks["height_true"][on_leg] - 1.0
    print(f"true height 1 m {np.sqrt(np.mean(error ** 2)) * 100:.1f} cm RMS, {np.abs(error).max() * 100:.1f} cm max; "
          f"climbed {ticks['z'][0] - ticks['z'][-1]:.2f} m")
    assert np.sqrt(np.mean(error ** 2)) <= 0.05 and ticks["height_true"][on_leg].min() > 0.8
    assert ticks["z"][0] - ticks["z"][-1] > 0.8                       # it went up the slope
    assert "the bottom lost" in output and "the bottom found again" in output
    dropout = (ticks["vehicle_time"] >= 40.0) & (ticks["vehicle_time"] <= 45.0)
    assert dropout.sum() > 50
    held = ticks["z_d"][dropout]
    print(f"dropout: depth reference {held[0]:.3f} -> {held.max():.3f} m at its deepest")
    assert held.max() <= held[0] + 0.005                               # never toward the bottom
    assert ticks["z"][dropout].max() <= ticks["z"][dropout][0] + 0.02


def test_a_bottom_rising_faster_than_the_run_climbs_is_climbed_at_the_limit_without_striking(tmp_path):
    """A ramp of 0.8 m over 1 m crossed at 0.5 m/s: the bottom rises at 0.4 m/s, the run climbs at its 0.3 m/s,
    says so, and the vehicle never comes within 0.3 m of the bottom."""
    ramp = {"profile": [[0.0, 8.0], [6.0, 8.0], [7.0, 7.2], [30.0, 7.2]]}
    code, output, ticks, metrics = fly(tmp_path, transect(tmp_path, ramp, {"preset": "ideal"}, length=12.0,
                                                          speed=0.5))
    assert code == 0 and metrics["completed"], output
    assert "climbing at the limit" in output
    on_leg = np.isfinite(ticks["height_true"])
    print(f"lowest true height {ticks['height_true'][on_leg].min():.2f} m")
    assert ticks["height_true"][on_leg].min() > 0.3
    assert ticks["z_dot_d"].min() >= -0.3 - 1e-6 and ticks["z_dot_d"].min() < -0.29   # climbed at the limit


def test_a_bottom_lost_for_good_stops_the_run_safely(tmp_path):
    sounder = {"preset": "ideal", "outages": [[30.0, 1000.0]]}
    code, output, _, metrics = fly(tmp_path, transect(tmp_path, {"depth": 8.0}, sounder, length=20.0))
    assert code != 0 and not metrics.get("completed", False), output
    assert "the bottom lost for" in output and "the leg stopped" in output
    assert "neutral 1500 us on channels 1-8: sent, confirmed by SERVO_OUTPUT_RAW" in output


def test_a_plans_terrain_waypoints_are_flown_at_their_height_up_a_slope(tmp_path):
    """A QGroundControl plan whose second waypoint is in altitude mode Terrain (MAV_FRAME_GLOBAL_TERRAIN_ALT,
    ArduSub's ABOVE_TERRAIN waypoint): flown 1 m above a 10 % slope, climbing it, held to the true bottom."""
    north = 8.0 / (EARTH_MEAN_RADIUS * math.pi / 180.0)            # degrees of latitude in 8 m
    items = [waypoint(1, HOME[0], HOME[1], -7.0), waypoint(2, HOME[0] + north, HOME[1], 1.0, frame=10)]
    write_plan(tmp_path / "terrain.plan", items)
    side = tmp_path / "dive.yaml"
    side.write_text(yaml.safe_dump({
        "name": "dive", "plan": "terrain.plan", "speed": 0.2,
        "environment": {"seafloor": {"depth": 8.0, "slope": 0.1},
                        "navigation": {"preset": "ideal", "echo_sounder": IDEAL_WITH}},
        "limits": {"max_depth": 12.0}}))
    code, output, ticks, metrics = fly(tmp_path, side)
    assert code == 0 and metrics["completed"], output
    on_leg = np.isfinite(ticks["height_true"]) & (ticks["x"] > 1.0)
    error = ticks["height_true"][on_leg] - 1.0
    print(f"true height 1 m {np.sqrt(np.mean(error ** 2)) * 100:.1f} cm RMS; climbed "
          f"{ticks['z'][0] - ticks['z'][-1]:.2f} m to x {ticks['x'][-1]:.2f} m")
    assert on_leg.sum() > 100 and np.sqrt(np.mean(error ** 2)) <= 0.05
    assert ticks["z"][0] - ticks["z"][-1] > 0.6 and ticks["x"][-1] > 7.5        # up the slope, to the waypoint
    assert metrics["terrain"]["strikes"] == 0
