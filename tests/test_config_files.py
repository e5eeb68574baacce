"""Vehicle and mission files: bad input fails before anything runs, with file, key and reason on one line."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
import yaml
from conftest import MISSIONS

from rov_mav.config import ConfigError
from rov_mav.mission.missions import load_mission
from rov_mav.model.vehicle import default_vehicle_path, load_flown_vehicle, load_vehicle


def write(tmp_path, name, data):
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data))
    return path


def vehicle_data():
    return yaml.safe_load(default_vehicle_path().read_text())


@pytest.mark.parametrize("change, pattern", [
    (lambda d: d.pop("mass"), r"vehicle.yaml: mass: missing"),
    (lambda d: d.update(colour="yellow"), r"vehicle.yaml: colour: unknown key"),
    (lambda d: d.update(mass="heavy"), r"vehicle.yaml: mass: .*number"),
    (lambda d: d.update(mass=-13.5), r"vehicle.yaml: mass: .*greater than 0"),
    (lambda d: d.update(inertia_products=[0.5, 0.0, 0.0]), r"vehicle.yaml: .*not positive definite"),
    (lambda d: d["thrusters"]["directions"].__setitem__(0, [1.0, 1.0, 0.0]),
     r"vehicle.yaml: thrusters.directions: .*thruster 1 direction is not a unit vector"),
    (lambda d: d["thrusters"]["directions"].pop(), r"vehicle.yaml: thrusters: .*directions lists 7 thrusters, "
                                                   r"positions 8"),
    (lambda d: d["thrusters"].update(per_thruster_scale=[1.0] * 6), r"per_thruster_scale lists 6 thrusters"),
    (lambda d: d.update(frame="vectored"), r"vehicle.yaml: .*vectored has 6 motors, thrusters lists 8"),
])
def test_bad_vehicle_file(tmp_path, change, pattern):
    data = vehicle_data()
    change(data)
    with pytest.raises(ConfigError, match=pattern) as info:
        load_vehicle(write(tmp_path, "vehicle.yaml", data))
    assert "\n" not in str(info.value)


def test_shipped_vehicle_is_the_reference_model(vehicle):
    assert vehicle.mass == 13.5
    np.testing.assert_allclose(np.diag(vehicle.mass_matrix), [19.857, 20.621, 32.19, 0.4458, 0.3648, 0.5915])


def test_a_six_thruster_vehicle_is_a_prior_and_refused_for_flight(tmp_path):
    """The shipped standard BlueROV2 (FRAME_CONFIG 1): six thrusters with their own scales; what flies or simulates
    refuses it in one line naming the file (the controller and the simulator drive eight)."""
    path = default_vehicle_path().parent / "vehicles" / "bluerov2.yaml"
    standard = load_vehicle(path)
    assert standard.frame.config == 1 and standard.thruster_positions.shape == (6, 3)
    assert standard.per_thruster_scale.shape == (6,)
    np.testing.assert_allclose(standard.buoyancy - standard.weight, 0.2 * standard.gravity, rtol=1e-9)
    with pytest.raises(ConfigError, match=r"bluerov2.yaml: BlueROV2 is FRAME_CONFIG 1 \(VECTORED, 6 motors\): "
                                          r"rov-mav flies and simulates 8-thruster vehicles only") as info:
        load_flown_vehicle(path)
    assert "\n" not in str(info.value)
    assert load_flown_vehicle().frame.config == 2


def square_data():
    return yaml.safe_load((MISSIONS / "square.yaml").read_text())


@pytest.mark.parametrize("change, pattern", [
    (lambda d: d.update(speed=0.3), r"m.yaml: speed: unknown key"),
    (lambda d: d["path"][0].update(speed=0.0), r"m.yaml: path\[0\].speed: .*greater than 0"),
    (lambda d: d["path"][0].update(speed="fast"), r"m.yaml: path\[0\].speed: .*number"),
    (lambda d: d["path"][1].update(heading=90), r"m.yaml: path\[1\].heading: .*degrees need a unit"),
    (lambda d: d["path"][1].update(heading="90 degrees"), r"m.yaml: path\[1\].heading: .*not an angle"),
    (lambda d: d["path"].insert(1, {"goto": [10.0, 0.0, 1.0], "speed": 0.2}),
     r"m.yaml: path\[1\].goto: zero-length segment"),
    (lambda d: d["path"][0].pop("speed"), r"m.yaml: path\[0\]: a goto needs a speed"),
    (lambda d: d["path"].__setitem__(0, {"hold": 3, "goto": [1.0, 2.0, 3.0], "speed": 1.0}),
     r"m.yaml: path\[0\]: each path entry needs exactly one of goto, hold, line"),
    (lambda d: d["environment"].update(disturbance=[1, 2, 3]), r"m.yaml: environment.disturbance: .*at least 6"),
    (lambda d: d.update(path=[]), r"m.yaml: path: .*at least 1"),
])
def test_bad_mission_file(tmp_path, change, pattern):
    data = square_data()
    change(data)
    with pytest.raises(ConfigError, match=pattern):
        load_mission(write(tmp_path, "m.yaml", data))


@pytest.mark.process
def test_bad_mission_exits_nonzero_with_one_line_and_writes_nothing(tmp_path):
    data = square_data()
    data["path"][0]["speed"] = -1
    bad = write(tmp_path, "bad.yaml", data)
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "rov_mav.cli", "simulate", str(bad), "--out", str(out)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert proc.stderr.strip().count("\n") == 0
    assert "bad.yaml: path[0].speed" in proc.stderr
    assert not out.exists()


def test_angles_accept_units(tmp_path):
    data = square_data()
    data["path"][1]["heading"] = "1.5707963267948966 rad"
    a = load_mission(write(tmp_path, "a.yaml", data))
    data["path"][1]["heading"] = "90 deg"
    b = load_mission(write(tmp_path, "b.yaml", data))
    np.testing.assert_allclose(a.reference(np.arange(0, 60, 0.5)), b.reference(np.arange(0, 60, 0.5)), atol=1e-12)


@pytest.mark.parametrize("name", ["line", "square", "under_ice_survey"])
def test_references_are_smooth_and_consistent(name):
    """eta_d, eta_dot_d, eta_ddot_d continuous (bounded change per small step) and each the derivative of the last."""
    mission = load_mission(MISSIONS / f"{name}.yaml")
    dt = 1e-3
    t = np.arange(0, mission.duration + 5, dt)
    ref = mission.reference(t)
    jumps = np.abs(np.diff(ref, axis=0)).max(axis=0)
    assert jumps[:6].max() < 1e-3 and jumps[6:12].max() < 1e-3 and jumps[12:].max() < 2e-2
    for lo, hi in ((0, 6), (6, 12)):
        numeric = np.gradient(ref[:, lo:hi], dt, axis=0)
        np.testing.assert_allclose(numeric[1:-1], ref[1:-1, hi:hi + 6], atol=5e-3)


def test_square_visits_its_corners_and_faces_along_each_side():
    mission = load_mission(MISSIONS / "square.yaml")
    ends = [seg.t0 + seg.duration for seg in mission.segments]
    corners = mission.reference(np.array(ends))[:, :3]
    np.testing.assert_allclose(corners[[0, 2, 4, 6]], [[10, 0, 1], [10, 10, 1], [0, 10, 1], [0, 0, 1]], atol=1e-12)
    headings = mission.reference(np.array([seg.t0 + seg.duration / 2 for seg in mission.segments[::2]]))[:, 5]
    np.testing.assert_allclose(np.cos(headings), [1, 0, -1, 0], atol=1e-12)
    np.testing.assert_allclose(np.sin(headings), [0, 1, 0, -1], atol=1e-12)


def test_line_is_report_eq_3_1():
    mission = load_mission(MISSIONS / "line.yaml")
    t = np.linspace(0, 90, 50)
    ref = mission.reference(t)
    expected = np.stack([0.2 * t, 0.2 * t, 0 * t, 0 * t, 0 * t, np.full_like(t, np.pi / 4)], -1)
    np.testing.assert_allclose(ref[:, :6], expected, atol=1e-12)
    np.testing.assert_allclose(mission.environment.disturbance, [-1, 1, 2, 0.1, 0.1, 0])
