"""QGroundControl `.plan` files -> missions: plans written as QGC writes them (waypoints with hold and yaw, a survey,
plans we must refuse), the conversion checked against geometry computed independently (haversine distances,
bearings, ArduSub's depth sign), and the shipped plan simulated end to end by the CLI."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import MISSIONS
from plan_helpers import (
    DO_CHANGE_SPEED,
    HOME,
    NAV_TAKEOFF,
    haversine,
    simple_item,
    survey,
    waypoint,
    write_plan,
)

from rov_mav.config import ConfigError
from rov_mav.mission.loader import load
from rov_mav.mission.mission_items import TURN_RATE, PlanOptions
from rov_mav.mission.missions import load_mission

ROV_MAV = str(Path(sys.executable).with_name("rov-mav"))
# WGS84's radii of curvature at 47.4 deg N are within 0.3 % of the haversine's mean sphere (meridian 0.02 %,
# prime vertical 0.29 %): local distances must agree with the haversine to that, and no better is expected.
SPHERE_TOLERANCE = 0.004
# Four waypoints as a user clicks them in QGC: ~20 m north, ~20 m east, back south; 2 m then 4 m deep.
CORNERS = [(47.3977419, 8.5455940), (47.3979219, 8.5455940), (47.3979219, 8.5458600), (47.3977419, 8.5458600)]


def _waypoints_plan(tmp_path: Path, **kwargs) -> Path:
    items = [waypoint(1, *CORNERS[0], -2.0),
             waypoint(2, *CORNERS[1], -2.0, hold=5),
             waypoint(3, *CORNERS[2], -4.0, yaw=270.0),
             waypoint(4, *CORNERS[3], -4.0)]
    return write_plan(tmp_path / "waypoints.plan", items, **kwargs)


def _targets(mission) -> list[np.ndarray]:
    """Start and the end pose (x, y, z, psi) of each goto segment."""
    out = [mission.segments[0].p0]
    out += [seg.p1 for seg in mission.segments if np.linalg.norm(seg.p1[:3] - seg.p0[:3]) > 0]
    return out


def test_waypoints_land_where_the_globe_puts_them_at_arduSubs_depth(tmp_path):
    mission = load(_waypoints_plan(tmp_path))
    targets = _targets(mission)
    assert len(targets) == 4
    for (a, b), (p, q) in zip(zip(CORNERS, CORNERS[1:]), zip(targets, targets[1:])):
        flat = math.hypot(*(q[:2] - p[:2]))
        assert flat == pytest.approx(haversine(a, b), rel=SPHERE_TOLERANCE)
    north, east, south = (q[:2] - p[:2] for p, q in zip(targets, targets[1:]))
    assert north[0] > 19 and abs(north[1]) < 0.01           # latitude grows northwards: +x
    assert east[1] > 19 and abs(east[0]) < 0.01             # longitude grows eastwards: +y
    assert south[0] < -19
    assert np.allclose(targets[0][:2], 0, atol=1e-6)        # the first waypoint is at the plan's home
    # ArduSub: altitude relative to home (the surface), negative below it -> NED depth positive down
    assert [t[2] for t in targets] == pytest.approx([2.0, 2.0, 4.0, 4.0])
    assert mission.origin == HOME[:2]


def test_hold_yaw_and_speed_shape_the_reference(tmp_path):
    mission = load(_waypoints_plan(tmp_path, cruise_speed=0.25))
    t = np.arange(0.0, mission.duration, 0.05)
    ref = mission.reference(t)
    speed = np.hypot(ref[:, 6], np.hypot(ref[:, 7], ref[:, 8]))
    assert speed.max() == pytest.approx(0.25, rel=1e-6)        # the plan's cruise speed, no faster
    # the 5 s hold at the second waypoint: standing still there
    second = _targets(mission)[1]
    still = (np.linalg.norm(ref[:, :3] - second[:3], axis=1) < 1e-9) & (speed < 1e-12)
    assert still.sum() * 0.05 >= 5.0
    # no yaw on the first leg: the vehicle faces along it (north); the third waypoint's yaw (270 deg: facing west
    # while it moves east) is reached by the end of its leg, without a stop to turn first; the last leg (south, no
    # yaw) starts with a turn in place to face south
    legs = [seg for seg in mission.segments if np.linalg.norm(seg.p1[:3] - seg.p0[:3]) > 0]
    assert legs[0].p0[3] == pytest.approx(0.0, abs=1e-9) and legs[0].p1[3] == pytest.approx(0.0, abs=1e-9)
    assert legs[1].p0[3] == pytest.approx(0.0, abs=1e-9) and legs[1].p1[3] == pytest.approx(-math.pi / 2)
    # (south on the meridian 20 m east: the tangent plane's north differs by the meridians' convergence, 3e-6 rad)
    assert abs(math.sin(legs[2].p0[3])) < 1e-5 and math.cos(legs[2].p0[3]) < 0
    turn = mission.segments[mission.segments.index(legs[2]) - 1]
    assert np.array_equal(turn.p0[:3], turn.p1[:3]) and turn.duration == pytest.approx(math.pi / 2 / TURN_RATE, rel=1e-4)
    faster = load(_waypoints_plan(tmp_path), PlanOptions(speed=0.5))
    assert faster.duration < mission.duration
    assert np.hypot(*faster.reference(np.arange(0, faster.duration, 0.05))[:, 6:8].T).max() == \
        pytest.approx(0.5, rel=1e-6)


def test_survey_flies_the_waypoints_qgc_stored_in_it(tmp_path):
    lanes = [((47.3977419, 8.545594 + k * 0.0000532), (47.3979219, 8.545594 + k * 0.0000532)) for k in range(4)]
    lanes = [lane if k % 2 == 0 else lane[::-1] for k, lane in enumerate(lanes)]
    path = write_plan(tmp_path / "survey.plan", [survey(1, lanes, depth=6.0)])
    mission = load(path)
    targets = _targets(mission)
    assert len(targets) == 8
    for k in range(4):
        along = math.hypot(*(targets[2 * k + 1][:2] - targets[2 * k][:2]))
        assert along == pytest.approx(haversine(*lanes[k]), rel=SPHERE_TOLERANCE)
    for k in range(3):
        across = math.hypot(*(targets[2 * k + 2][:2] - targets[2 * k + 1][:2]))
        assert across == pytest.approx(haversine(lanes[k][1], lanes[k + 1][0]), rel=SPHERE_TOLERANCE)
    assert all(t[2] == pytest.approx(6.0) for t in targets)


def test_a_corridor_scan_flies_its_stored_waypoints_and_change_speed_applies_after_it(tmp_path):
    lanes = [((47.3977419, 8.545594), (47.3979219, 8.545594)), ((47.3979219, 8.5456472), (47.3977419, 8.5456472))]
    corridor = survey(1, lanes, depth=3.0)
    corridor.update(complexItemType="CorridorScan", CorridorWidth=4, EntryPoint=0, version=3,
                    polyline=[[47.3977419, 8.5456206], [47.3979219, 8.5456206]])
    for key in ("angle", "entryLocation", "flyAlternateTransects", "polygon", "splitConcavePolygons"):
        del corridor[key]
    items = [waypoint(1, *CORNERS[0], -3.0), simple_item(2, DO_CHANGE_SPEED, [1, 0.15, -1, 0, 0, 0, 0], frame=2),
             corridor]
    mission = load(write_plan(tmp_path / "corridor.plan", items, cruise_speed=0.3))
    assert len(_targets(mission)) == 4      # the first waypoint is the corridor's entry: no leg to it, no stop
    legs = [seg for seg in mission.segments if np.linalg.norm(seg.p1[:3] - seg.p0[:3]) > 0]
    for seg in legs:                                   # every leg after DO_CHANGE_SPEED flies at 0.15 m/s
        t = np.linspace(seg.t0, seg.t0 + seg.duration, 400)
        assert np.hypot(*mission.reference(t)[:, 6:9].T).max() == pytest.approx(0.15, rel=1e-6)


def test_a_survey_with_camera_triggers_is_refused_or_flown_without_them(tmp_path):
    lanes = [((47.3977419, 8.545594), (47.3979219, 8.545594)), ((47.3979219, 8.5456472), (47.3977419, 8.5456472))]
    path = write_plan(tmp_path / "camera.plan", [survey(1, lanes, depth=3.0, trigger_distance=5.0)])
    with pytest.raises(ConfigError) as refused:
        load(path)
    assert "mission.items[0].TransectStyleComplexItem.Items[1] (DO_SET_CAM_TRIGG_DIST)" in str(refused.value)
    assert "--skip-unflyable" in str(refused.value)
    mission = load(path, PlanOptions(skip_unflyable=True))
    assert len(mission.skipped) == 4 and all("DO_SET_CAM_TRIGG_DIST" in line for line in mission.skipped)
    assert len(_targets(mission)) == 4


def test_the_shipped_survey_plan_is_the_shipped_yaml_survey(tmp_path):
    plan = load(MISSIONS / "under_ice_survey.plan")
    yaml = load_mission(MISSIONS / "under_ice_survey.yaml")
    plan_points = np.array([t[:3] for t in _targets(plan)])
    yaml_points = np.array([t[:3] for t in _targets(yaml)])
    assert plan_points.shape == yaml_points.shape == (8, 3)
    assert np.abs(plan_points - yaml_points).max() < 0.005       # 5 mm: the plan stores 1e-9 degrees
    assert plan.limits.max_depth is None and not np.any(plan.environment.current)   # a plan alone: still water
    # named from a YAML with the YAML survey's ramps, environment and limits, the plan is that mission: the turns in
    # place the conversion adds (90 deg at 15 deg/s) are the YAML's 6 s holds
    side = tmp_path / "dive.yaml"
    side.write_text(f"name: dive\nplan: {MISSIONS / 'under_ice_survey.plan'}\nramp_time: 3.0\n"
                    f"environment: {{current: [0.04, 0.03, 0.0]}}\nlimits: {{max_depth: 10.0}}\n")
    named = load(side)
    assert named.duration == pytest.approx(yaml.duration, abs=0.01)
    t = np.arange(0.0, yaml.duration, 0.1)
    difference = named.reference(t) - yaml.reference(t)
    assert np.abs(difference[:, :6]).max() < 0.005 and np.abs(difference[:, 6:]).max() < 0.001


@pytest.mark.parametrize("items,options,expected", [
    ([waypoint(1, *CORNERS[0], -2.0), waypoint(2, *CORNERS[1], 2.0)], PlanOptions(),
     "mission.items[1] (NAV_WAYPOINT): altitude +2 m is above the surface"),
    ([simple_item(1, NAV_TAKEOFF, [0, 0, 0, None, *CORNERS[0], 10]), waypoint(2, *CORNERS[1], -2.0),
      waypoint(3, *CORNERS[2], -2.0)], PlanOptions(), "cannot fly mission.items[0] (NAV_TAKEOFF)"),
    ([waypoint(1, *CORNERS[0], 486.0, frame=0), waypoint(2, *CORNERS[1], 486.0, frame=0)], PlanOptions(),
     "mission.items[0] (NAV_WAYPOINT): altitude frame GLOBAL (above mean sea level): ArduSub flies altitudes "
     "relative to home"),
    ([waypoint(1, *CORNERS[0], 1.0, frame=10), waypoint(2, *CORNERS[1], 1.0, frame=10)], PlanOptions(),
     "mission.items[0] (NAV_WAYPOINT): a height above the bottom needs a waypoint with a depth before it"),
    ([waypoint(1, *CORNERS[0], -2.0), waypoint(2, *CORNERS[1], -1.0, frame=11)], PlanOptions(),
     "mission.items[1] (NAV_WAYPOINT): altitude -1 m above the terrain: a height above the bottom is positive"),
    ([waypoint(1, *CORNERS[0], 0.0), waypoint(2, *CORNERS[1], -2.0)], PlanOptions(),
     "mission.items[0] (NAV_WAYPOINT): altitude 0 (the depth the vehicle is at) needs a waypoint before it"),
    ([waypoint(1, *CORNERS[0], -2.0), waypoint(2, *CORNERS[1], -2.0)], PlanOptions(speed=15.0),
     "--plan-speed: speed 15 m/s is beyond what a BlueROV2 Heavy flies"),
    ([waypoint(1, *CORNERS[0], -2.0), waypoint(2, 47.5, 8.545594, -2.0)], PlanOptions(),
     "mission.items[1] (NAV_WAYPOINT): 11.4 km from the origin"),
    ([waypoint(1, *CORNERS[0], -2.0), {"type": "ComplexItem", "complexItemType": "StructureScan", "version": 3,
                                       "polygon": [list(c) for c in CORNERS], "Layers": 1}], PlanOptions(),
     "cannot fly mission.items[1] (StructureScan complex item: QGC stores no waypoints in it)"),
])
def test_plans_we_must_refuse_are_refused_naming_the_item(tmp_path, items, options, expected):
    path = write_plan(tmp_path / "bad.plan", items)
    with pytest.raises(ConfigError) as refused:
        load(path, options)
    assert expected in str(refused.value)
    assert str(refused.value).startswith(str(path)) and "\n" not in str(refused.value)


def test_takeoff_is_skipped_when_asked_and_listed(tmp_path):
    items = [simple_item(1, NAV_TAKEOFF, [0, 0, 0, None, *CORNERS[0], 10]), waypoint(2, *CORNERS[0], -2.0),
             waypoint(3, *CORNERS[1], -2.0)]
    mission = load(write_plan(tmp_path / "takeoff.plan", items), PlanOptions(skip_unflyable=True))
    assert mission.skipped == ("skipped mission.items[0] (NAV_TAKEOFF)",)
    assert [t[2] for t in _targets(mission)] == pytest.approx([2.0, 2.0])


def test_qgc_default_cruise_speed_is_refused(tmp_path):
    with pytest.raises(ConfigError, match=r"mission.cruiseSpeed: speed 15 m/s is beyond"):
        load(_waypoints_plan(tmp_path, cruise_speed=15))


def test_a_yaml_names_a_plan_and_gives_it_environment_and_limits(tmp_path):
    _waypoints_plan(tmp_path)
    side = tmp_path / "dive.yaml"
    side.write_text("name: dive\nplan: waypoints.plan\nspeed: 0.2\nenvironment: {current: [0.05, 0, 0]}\n"
                    "limits: {max_depth: 10}\n")
    mission = load(side)
    assert mission.name == "dive" and mission.environment.current[0] == 0.05 and mission.limits.max_depth == 10
    side.write_text("name: dive\nplan: waypoints.plan\nlimits: {max_depth: 3}\n")
    with pytest.raises(ConfigError, match=r"waypoints.plan: mission.items\[2\]: depth 4 m is past limits.max_depth"):
        load(side)


def _cli(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([ROV_MAV, *args], capture_output=True, text=True, cwd=cwd, timeout=300)


@pytest.mark.process
@pytest.mark.parametrize("command", ["simulate", "run", "tune"])
def test_a_refused_plan_stops_every_command_before_anything_starts(tmp_path, command):
    path = write_plan(tmp_path / "above.plan", [waypoint(1, *CORNERS[0], -2.0), waypoint(2, *CORNERS[1], 1.5)])
    r = _cli(command, str(path), "--rerun", "off", cwd=tmp_path)
    assert r.returncode == 2
    assert r.stderr.strip().splitlines() == [
        f"rov-mav {command}: error: {path}: mission.items[1] (NAV_WAYPOINT): altitude +1.5 m is above the surface: "
        f"ArduSub reads an altitude relative to home, the surface, so 1.5 m deep is -1.5"]
    assert "Traceback" not in r.stderr and "built-in vehicle" not in r.stdout
    assert not (tmp_path / "out").exists()                     # nothing half-written


@pytest.mark.process
def test_run_refuses_a_plan_deeper_than_max_depth_before_anything_moves(tmp_path):
    r = _cli("run", str(_waypoints_plan(tmp_path)), "--max-depth", "3", "--rerun", "off", cwd=tmp_path)
    assert r.returncode == 2
    assert "mission.items[2]: depth 4 m is past --max-depth 3 m" in r.stderr
    assert "built-in vehicle" not in r.stdout


@pytest.mark.process
def test_simulate_flies_the_shipped_survey_plan(tmp_path):
    metrics_path = tmp_path / "metrics.json"
    r = _cli("simulate", str(MISSIONS / "under_ice_survey.plan"), "--rerun", "off", "--out", str(tmp_path / "fig"),
             "--metrics", str(metrics_path), cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    metrics = json.loads(metrics_path.read_text())
    mission = load(MISSIONS / "under_ice_survey.plan")
    print(f"under_ice_survey.plan simulated: {metrics['duration_s']:.1f} s, RMS "
          f"{metrics['rms_position_error_m'] * 100:.3f} cm, max {metrics['max_position_error_m'] * 100:.3f} cm")
    assert metrics["completed"] and metrics["duration_s"] == pytest.approx(mission.duration, abs=0.02)
    assert metrics["max_position_error_m"] < 0.05
    assert (tmp_path / "fig" / "path3d.png").exists()


@pytest.mark.parametrize("args", [["--mission-from-vehicle"], [], ["square", "--mission-from-vehicle",
                                                                    "--target", "udp:127.0.0.1:14550"]])
@pytest.mark.process
def test_run_wants_one_mission_source_and_a_vehicle_to_download_from(tmp_path, args):
    r = _cli("run", *args, "--rerun", "off", cwd=tmp_path)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert r.stderr.strip() == ("rov-mav run: error: give a mission (a shipped mission's name or a file), or "
                                "--mission-from-vehicle with --target (the built-in vehicle starts with no mission)")


def test_terrain_frame_waypoints_become_altitude_legs_and_the_turns_between_them_keep_the_height(tmp_path):
    """QGC's altitude mode Terrain (MAV_FRAME_GLOBAL_TERRAIN_ALT, and its _INT twin): ArduSub's ABOVE_TERRAIN
    waypoints (PR #26450), a height above the bottom its rangefinder sees; here altitude legs, planned at the depth
    before them, the holds and turns in place at such a waypoint holding its height too."""
    items = [waypoint(1, *CORNERS[0], -6.0), waypoint(2, *CORNERS[1], 1.5, hold=4, frame=10),
             waypoint(3, *CORNERS[2], 1.0, frame=11), waypoint(4, *CORNERS[3], -5.0)]
    mission = load(write_plan(tmp_path / "terrain.plan", items))
    legs = [(label, seg.terrain, round(float(seg.p1[2]), 3)) for label, seg in zip(mission.labels, mission.segments)]
    assert legs == [("mission.items[1]", ("altitude", 1.5), 6.0),            # the leg to it, planned at 6 m
                    ("mission.items[1]", ("altitude", 1.5), 6.0),            # its 4 s hold
                    ("mission.items[2] (turn)", ("altitude", 1.5), 6.0),     # turning where 1.5 m was held
                    ("mission.items[2]", ("altitude", 1.0), 6.0),
                    ("mission.items[3] (turn)", ("altitude", 1.0), 6.0),
                    ("mission.items[3]", None, 5.0)]                         # a depth again
    assert mission.follows_terrain
