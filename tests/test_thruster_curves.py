"""Vehicle files that name their thrusters' force law: the quadratic curve (ArduPilot SITL's submarine) and the SITL
vehicle file, checked against SIM_Submarine.cpp's formulas written out here independently."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml
from mixer_oracle import ARDUSUB_FACTORS, FORWARD, LATERAL, PITCH, ROLL, THROTTLE, YAW

from rov_mav.config import ConfigError
from rov_mav.flight.thrusters.actuation import Actuation
from rov_mav.model.thrusters import Allocator, ThrusterMap, allocation_matrix, load_t200, thruster_curve
from rov_mav.model.vehicle import QuadraticCurve, default_vehicle_path, load_vehicle, save_vehicle

ROOT = Path(__file__).resolve().parents[1]
SITL_VEHICLE = ROOT / "vehicles" / "ardusub_sitl.yaml"
PWMS = np.arange(1100, 1901)


def sitl_output(pwm: np.ndarray) -> np.ndarray:
    """SIM_Submarine::calculate_forces: o = (pwm - 1500) / 400 outside 1475..1525 (and inside 1000..2000)."""
    live = (pwm > 1000) & (pwm < 2000) & ((pwm < 1475) | (pwm > 1525))
    return np.where(live, (pwm - 1500) / 400.0, 0.0)


def sitl_wrench(pwm: np.ndarray) -> np.ndarray:
    """SITL's body force (N, on its 10.5 kg) and moment (N m) from 8 PWMs: linear factors * o|o| * 51.48 N, moments
    0.25 m * rotational factors * the same thrust."""
    thrust = np.abs(sitl_output(pwm)) * sitl_output(pwm) * 51.48
    f = ARDUSUB_FACTORS
    linear = np.column_stack([f[:, FORWARD], f[:, LATERAL], -f[:, THROTTLE]])
    rotational = np.column_stack([f[:, ROLL], f[:, PITCH], f[:, YAW]])
    return np.concatenate([linear.T @ thrust, 0.25 * rotational.T @ thrust])


@pytest.fixture(scope="module")
def sitl_vehicle():
    return load_vehicle(SITL_VEHICLE)


def test_the_default_vehicle_keeps_the_t200(vehicle):
    assert vehicle.thruster_curve is None
    assert thruster_curve(vehicle).max_forward(16.0) > 40.0


def test_thrust_scale_multiplies_the_quadratic_law_too(sitl_vehicle):
    """One law: a vehicle file's thrust_scale (forward, reverse) scales the quadratic curve as it scales the T200."""
    weaker = replace(sitl_vehicle, thrust_scale=np.array([0.8, 0.6]))
    pwm = np.array([1700.0, 1300.0] * 4)
    assert np.allclose(thruster_curve(weaker).thrust(pwm, 12.0),
                       np.array([0.8, 0.6] * 4) * thruster_curve(sitl_vehicle).thrust(pwm, 12.0))
    t200 = load_t200()
    assert np.allclose(t200.scaled(0.8, 0.6).thrust(pwm, 14.0), np.array([0.8, 0.6] * 4) * t200.thrust(pwm, 14.0))


def test_quadratic_thrust_is_sitls_law():
    curve = ThrusterMap.quadratic(QuadraticCurve(np.full(8, 51.48), np.full(8, 51.48), (1475.0, 1525.0), 400.0))
    expected = np.abs(sitl_output(PWMS)) * sitl_output(PWMS) * 51.48
    assert np.allclose(curve.thrust(PWMS[:, None].repeat(8, axis=1), 12.0)[:, 0], expected)
    assert curve.dead_band(12.0) == (1475.0, 1525.0)


def test_quadratic_pwm_inverts_thrust_per_thruster_and_direction():
    curve = ThrusterMap.quadratic(QuadraticCurve(np.array([72.8] * 4 + [51.48] * 4), np.array([60.0] * 8),
                                                 (1475.0, 1525.0), 400.0))
    thrusts = np.array([30.0, -20.0, 0.5, -59.0, 51.0, -3.0, 0.3, 10.0])
    pwm = curve.pwm(thrusts, 12.0)
    assert np.allclose(curve.thrust(pwm, 12.0), thrusts)
    assert curve.pwm(np.zeros(8), 12.0).tolist() == [1500.0] * 8
    tiny = curve.pwm(np.array([0.01, -0.01] * 4), 12.0)
    assert np.all((tiny[::2] > 1525.0) & (tiny[::2] < 1526.0))         # between the band's edge and the first live
    assert np.all((tiny[1::2] < 1475.0) & (tiny[1::2] > 1474.0))       # microsecond, never inside the band
    huge = curve.pwm(np.array([500.0, -500.0] * 4), 12.0)
    assert huge.tolist() == [1900.0, 1100.0] * 4
    with pytest.raises(ValueError):
        curve.pwm(np.full(8, np.nan), 12.0)


def test_sitl_vehicle_file_reproduces_sitls_wrench(sitl_vehicle):
    """Every thruster alone and a random mix: B f(pwm) of the file equals SIM_Submarine's wrench."""
    matrix = allocation_matrix(sitl_vehicle.thruster_positions, sitl_vehicle.thruster_directions)
    curve = thruster_curve(sitl_vehicle)
    rng = np.random.default_rng(1)
    cases = [np.where(np.arange(8) == i, p, 1500.0) for i in range(8) for p in (1300.0, 1700.0, 1530.0)]
    cases += [rng.integers(1100, 1901, 8).astype(float) for _ in range(20)]
    for pwm in cases:
        assert np.allclose(matrix @ curve.thrust(pwm, 12.6), sitl_wrench(pwm), atol=1e-3), pwm


def test_sitl_vehicle_horizontal_thrusters_have_no_pitch_or_roll_arm(sitl_vehicle):
    """So the allocation never uses them for pitch or roll (SITL's vectored_6dof gives them yaw only)."""
    matrix = allocation_matrix(sitl_vehicle.thruster_positions, sitl_vehicle.thruster_directions)
    assert np.allclose(matrix[3:5, :4], 0.0)
    allocator = Allocator.for_vehicle(sitl_vehicle, 12.6)
    thrusts, _ = allocator.thrusts(np.array([0.0, 0.0, 0.0, 0.0, 1.5, 0.0]))      # pitch alone
    assert np.allclose(thrusts[:4], 0.0, atol=1e-9)
    thrusts, _ = allocator.thrusts(np.array([20.0, 0.0, 0.0, 0.0, 0.0, 0.0]))     # surge alone
    assert np.allclose(thrusts[4:], 0.0, atol=1e-9)


def test_sitl_vehicle_mass_drag_and_restoring(sitl_vehicle):
    v = sitl_vehicle
    assert np.allclose(np.diag(v.mass_matrix), [10.5, 10.5, 10.5, 0.26808, 0.26808, 0.26808], atol=1e-4)
    assert v.buoyancy - v.weight == pytest.approx(10.5 / 16.75516, abs=1e-3)      # SIM_BUOYANCY 1 on the sphere
    assert -v.center_of_buoyancy[2] * v.buoyancy == pytest.approx(6.0, abs=1e-3)  # 40 N at 0.15 m
    area = np.pi / 4 * (0.0335103 * 3 / 4) ** (2 / 3)
    assert np.allclose(v.quadratic_damping[:3], 0.5 * 1023.6 * area * np.array([1.4, 1.8, 2.0]), rtol=1e-4)


def test_actuation_on_the_quadratic_law_caps_each_thruster(sitl_vehicle):
    act = Actuation(sitl_vehicle, max_thrust=40.0, voltage=12.6)
    low, high = act.pwm_range
    assert np.allclose(high[:4], 1500 + np.ceil(400 * np.sqrt(40 / 72.8037)))    # horizontal: 72.8 N full scale
    assert np.allclose(high[4:], 1500 + np.ceil(400 * np.sqrt(40 / 51.48)))      # vertical: 51.48 N
    thrusts, pwm, _ = act.command(np.array([15.0, -5.0, 8.0, 0.2, -0.3, 0.4]))
    curve = thruster_curve(sitl_vehicle)
    assert np.allclose(curve.thrust(pwm, 12.6), thrusts, atol=0.15)               # 1 us of rounding
    assert "(" in act.describe_range()                                            # two ranges: per thruster


@pytest.mark.parametrize("curve, pattern", [
    ({"quadratic": {"max_thrust": -1.0}}, r"thrusters.curve.*greater than 0"),
    ({"quadratic": {"max_thrust": 50.0, "dead_band": [1510, 1525]}}, r"thrusters.curve.*dead_band must hold 1500"),
    ({"quadratic": {"max_thrust": [50.0, 50.0]}},
     r"thrusters: curve.quadratic.max_thrust lists 2 thrusters, positions 8"),
    ("cubic", r"thrusters.curve"),
])
def test_bad_curve_is_one_line(tmp_path, curve, pattern):
    data = yaml.safe_load(default_vehicle_path().read_text())
    data["thrusters"]["curve"] = curve
    path = tmp_path / "vehicle.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match=pattern) as info:
        load_vehicle(path)
    assert "\n" not in str(info.value)


def test_saved_vehicle_keeps_its_quadratic_law(sitl_vehicle, tmp_path):
    """identify writes vehicle files with save_vehicle: a SITL prior's law must survive it."""
    save_vehicle(replace(sitl_vehicle, thrust_scale=np.array([0.9, 1.1])), tmp_path / "fitted.yaml")
    fitted = load_vehicle(tmp_path / "fitted.yaml")
    pwm = np.array([1650.0, 1350.0] * 4)
    assert np.allclose(thruster_curve(fitted).thrust(pwm, 12.0),
                       np.array([0.9, 1.1] * 4) * thruster_curve(sitl_vehicle).thrust(pwm, 12.0))


@pytest.mark.parametrize("vehicle_file", [SITL_VEHICLE, default_vehicle_path()])
def test_error_diffusion_averages_to_the_thrust_asked(vehicle_file):
    """A wrench whose thrusts sit inside the dead band's edge step or between whole-us PWMs: rounded tick by tick
    the vehicle gets the wrong average wrench (nothing at all in SITL's dead band), diffused it gets the asked one."""
    vehicle = load_vehicle(vehicle_file)
    tau = np.array([0.3, -0.2, 0.6, 0.01, -0.02, 0.015])          # a hover trim: tenths of a newton per thruster
    matrix = allocation_matrix(vehicle.thruster_positions, vehicle.thruster_directions)
    curve = thruster_curve(vehicle)
    averages = {}
    for diffuse in (True, False):
        act = Actuation(vehicle, max_thrust=40.0, voltage=12.6, diffuse=diffuse, pretension=False)
        wrenches = [matrix @ curve.thrust(act.command(tau)[1], 12.6) for _ in range(500)]
        averages[diffuse] = np.mean(wrenches, axis=0)
    assert np.allclose(averages[True], tau, atol=[0.01, 0.01, 0.01, 0.001, 0.001, 0.001])
    assert not np.allclose(averages[False], tau, atol=[0.01, 0.01, 0.01, 0.001, 0.001, 0.001])


def test_error_diffusion_carries_nothing_past_saturation_or_a_reset(sitl_vehicle):
    act = Actuation(sitl_vehicle, max_thrust=40.0, voltage=12.6, pretension=False)
    act.command(np.array([500.0, 0.0, 0.0, 0.0, 0.0, 0.0]))            # far beyond the cap: saturated
    assert np.all(np.abs(act.carry) <= 1.0)
    act.command(np.array([0.0, 0.0, 0.1, 0.0, 0.0, 0.0]))
    assert np.any(act.carry != 0.0)
    act.reset()
    assert act.command(np.zeros(6))[1].tolist() == [1500.0] * 8


def test_pretension_keeps_every_thruster_out_of_the_dead_band_with_the_same_wrench(sitl_vehicle):
    """The hover trim: rounded alone, SITL's thrusters sit in or at their dead band; pretensioned, every PWM is at
    least 5 us beyond it and the average wrench is still the one asked."""
    tau = np.array([0.3, -0.2, 0.6, 0.01, -0.02, 0.015])
    matrix = allocation_matrix(sitl_vehicle.thruster_positions, sitl_vehicle.thruster_directions)
    curve = thruster_curve(sitl_vehicle)
    act = Actuation(sitl_vehicle, max_thrust=40.0, voltage=12.6)
    pwms = np.array([act.command(tau)[1] for _ in range(200)])
    assert np.all(np.abs(pwms - 1500) >= 25 + 5 - 1)                    # 1 us of rounding
    wrench = np.mean([matrix @ curve.thrust(p, 12.6) for p in pwms], axis=0)
    assert np.allclose(wrench, tau, atol=[0.01, 0.01, 0.01, 0.001, 0.001, 0.001])
    plain = Actuation(sitl_vehicle, max_thrust=40.0, voltage=12.6, pretension=False).command(tau)[1]
    assert np.any(np.abs(plain - 1500) <= 25)


def test_sitl_prior_is_sitls_measured_vehicle_with_the_bluerov2s_hydrodynamics(sitl_vehicle, vehicle):
    """identify's prior for SITL: what a scale, a ruler and the thrusters' data give, the rest left to the fit."""
    prior = load_vehicle(SITL_VEHICLE.with_name("ardusub_sitl_prior.yaml"))
    for name in ("mass", "volume", "inertia_tensor", "center_of_gravity", "thruster_positions", "thruster_directions"):
        assert np.allclose(getattr(prior, name), getattr(sitl_vehicle, name)), name
    assert np.allclose(thruster_curve(prior).thrust(PWMS[:, None].repeat(8, axis=1), 12.6),
                       thruster_curve(sitl_vehicle).thrust(PWMS[:, None].repeat(8, axis=1), 12.6))
    for name in ("added_mass", "linear_damping", "quadratic_damping"):
        assert np.allclose(getattr(prior, name), getattr(vehicle, name)), name


@pytest.mark.parametrize("vehicle_file", [SITL_VEHICLE, default_vehicle_path()])
def test_saturated_actuation_gives_way_on_translation_not_on_roll_and_pitch(vehicle_file):
    """A surge and heave demand far beyond the cap with a little pitch: the thrust sent keeps the pitch and roll asked
    (within 10 %), and what is lost is force."""
    vehicle = load_vehicle(vehicle_file)
    act = Actuation(vehicle, max_thrust=40.0, voltage=12.6, diffuse=False, pretension=False)
    tau = np.array([300.0, 80.0, 250.0, 0.0, 1.5, 0.2])
    thrusts, _, info = act.command(tau)
    assert info.saturated
    achieved = allocation_matrix(vehicle.thruster_positions, vehicle.thruster_directions) @ thrusts
    assert abs(achieved[3]) < 0.03 and achieved[4] == pytest.approx(1.5, rel=0.1)   # all axes alike: 0 or 8.4
    assert achieved[0] < 0.9 * tau[0]
