"""Thruster module: allocation matrix signs, T200 map and its inverse, allocation within limits."""

from __future__ import annotations

import hashlib
from importlib import resources

import numpy as np
import pytest
from mixer_oracle import ARDUSUB_FACTORS, FORWARD, LATERAL, PITCH, ROLL, THROTTLE, YAW

from rov_mav.model.thrusters import (
    Allocator,
    ThrusterMap,
    allocate,
    allocation_matrix,
    load_t200,
    pwms_to_thrusts,
    thrusts_to_pwms,
)
from rov_mav.model.vehicle import load_vehicle

PACKAGE_CSV = resources.files("rov_mav") / "data" / "t200_performance.csv"
SHEET_VOLTAGES = [10.0, 12.0, 14.0, 16.0, 18.0, 20.0]
VOLTAGES = SHEET_VOLTAGES + [11.1, 14.8, 15.6, 16.8, 19.3]

X, Y, Z, K, M, N = range(6)

# Flat runs the monotone correction creates on the sheets: (voltage, PWM nearest 1500, PWM farthest). pwm(thrust(p))
# returns the PWM nearest 1500 for p anywhere in the run.
PLATEAUS = [(10.0, 1696, 1700), (12.0, 1104, 1100), (12.0, 1892, 1896), (14.0, 1896, 1900), (18.0, 1132, 1128)]


@pytest.fixture(scope="module")
def vehicle():
    return load_vehicle()


@pytest.fixture(scope="module")
def B(vehicle):
    return allocation_matrix(vehicle.thruster_positions, vehicle.thruster_directions)


@pytest.fixture(scope="module")
def t200():
    return load_t200()


@pytest.fixture(scope="module")
def raw():
    return np.genfromtxt(str(PACKAGE_CSV), delimiter=",", names=True)


# ---- allocation matrix ---------------------------------------------------------------------------------------


def test_allocation_matrix_hand_check(B):
    assert B.shape == (6, 8)
    s = np.sqrt(0.5)
    # T1 at (0.156, 0.111, 0.085) pushing along (-s, s, 0): r x e = (-0.085 s, -0.085 s, 0.156 s + 0.111 s).
    np.testing.assert_allclose(B[:, 0], [-s, s, 0, -0.085 * s, -0.085 * s, 0.267 * s], atol=1e-8)
    # T6 at (0.120, -0.218, 0) pushing down: r x e = (-0.218, -0.120, 0).
    np.testing.assert_allclose(B[:, 5], [0, 0, 1, -0.218, -0.120, 0], atol=1e-12)
    assert np.linalg.matrix_rank(B) == 6


def test_allocation_matrix_rejects_bad_shapes():
    with pytest.raises(ValueError):
        allocation_matrix(np.zeros((8, 3)), np.zeros((8, 2)))


@pytest.mark.parametrize(
    "thrusts, axis",
    [
        ([-1, -1, 1, 1, 0, 0, 0, 0], X),   # SITL: servos 1,2 below 1500, 3,4 above -> forward
        ([1, -1, -1, 1, 0, 0, 0, 0], N),   # SITL: 1,4 above, 2,3 below -> yaw clockwise from above
        ([0, 0, 0, 0, 1, 1, 1, 1], Z),     # SITL: 5-8 above -> down
    ],
)
def test_sitl_patterns(B, thrusts, axis):
    w = B @ np.array(thrusts, dtype=float)
    assert w[axis] > 0.5
    others = [a for a in (X, Y, Z, N) if a != axis]
    assert np.all(np.abs(w[others]) < 2e-3)
    if axis != X:   # forward thrust 0.085 m below the origin pitches the nose up; the other two are moment-free
        assert np.all(np.abs(w[[K, M]]) < 2e-3)


@pytest.mark.parametrize(
    "factor, axis, sign",
    [(FORWARD, X, +1), (LATERAL, Y, +1), (THROTTLE, Z, -1), (YAW, N, +1), (ROLL, K, +1), (PITCH, M, +1)],
)
def test_ardusub_mixer_consistent_with_B(B, factor, axis, sign):
    w = B @ ARDUSUB_FACTORS[:, factor]
    assert sign * w[axis] > 0.5 * np.abs(w).max()
    # The horizontal thrusters sit 0.085 m below the origin, so X and Y come with a pitch / roll moment of 0.085 X
    # (resp. -0.085 Y); everything else is zero up to the 1 mm asymmetry of the thruster positions.
    expected_coupling = {X: {M: 0.085 * w[X]}, Y: {K: -0.085 * w[Y]}}.get(axis, {})
    for a in range(6):
        if a != axis:
            np.testing.assert_allclose(w[a], expected_coupling.get(a, 0.0), atol=2e-3)


# ---- T200 map ------------------------------------------------------------------------------------------------


# SHA-256 of rov_mav/data/t200_performance.csv as checked byte for byte against Blue Robotics' T200 performance
# data (September 2019 release): a change to the file must be deliberate.
T200_SHA256 = "1a40df4c1b5653f3d67cff1893fc5db2d2385bdfb832be9913c88ba770117ab6"


def test_package_csv_is_blue_robotics_data(raw):
    """Blue Robotics' sheets as released: 201 PWMs (1100..1900 us every 4 us) at each of 6 voltages, thrust in
    kgf and in N (x 9.80665), reverse below 1500 us; the file unchanged since it was checked against the release."""
    assert raw.dtype.names == ("voltage_v", "pwm_us", "rpm", "current_a", "power_w", "force_kgf", "force_n")
    assert len(raw) == 6 * 201
    for voltage in SHEET_VOLTAGES:
        sheet = raw[raw["voltage_v"] == voltage]
        np.testing.assert_array_equal(sheet["pwm_us"], np.arange(1100, 1901, 4))
        pwm, force = sheet["pwm_us"], sheet["force_n"]
        assert np.all(force[pwm < 1460] < 0) and np.all(force[pwm > 1540] > 0)
    np.testing.assert_allclose(raw["force_n"], raw["force_kgf"] * 9.80665, atol=6e-4)
    assert hashlib.sha256(PACKAGE_CSV.read_bytes()).hexdigest() == T200_SHA256


def test_load_is_cached(t200):
    assert load_t200() is t200


@pytest.mark.parametrize("voltage", SHEET_VOLTAGES)
def test_thrust_reproduces_sheets(t200, raw, voltage):
    sheet = raw[raw["voltage_v"] == voltage]
    got = t200.thrust(sheet["pwm_us"], voltage)
    # Monotone correction changes only a handful of points, by at most 0.14 N.
    diff = np.abs(got - sheet["force_n"])
    assert diff.max() < 0.14
    assert np.count_nonzero(diff) <= 2
    assert np.all(np.diff(got) >= 0)
    np.testing.assert_allclose(t200.current(sheet["pwm_us"], voltage), sheet["current_a"], atol=1e-12)


def test_thrust_matches_coarse_reference_table(t200):
    pwm = [1100, 1200, 1300, 1400, 1500, 1600, 1700, 1800, 1900]
    table = {
        12.0: [-28.5, -19.1, -10.0, -3.1, 0, 3.9, 12.5, 24.2, 36.4],
        16.0: [-39.9, -26.6, -14.1, -4.7, 0, 5.9, 17.9, 33.5, 51.4],
    }
    for v, expected in table.items():
        np.testing.assert_allclose(t200.thrust(pwm, v), expected, atol=0.15)


def test_voltage_interpolation_and_clamping(t200):
    pwm = np.linspace(1100, 1900, 57)
    at14, at16 = t200.thrust(pwm, 14.0), t200.thrust(pwm, 16.0)
    np.testing.assert_allclose(t200.thrust(pwm, 14.8), 0.6 * at14 + 0.4 * at16, atol=1e-12)
    np.testing.assert_array_equal(t200.thrust(pwm, 7.0), t200.thrust(pwm, 10.0))
    np.testing.assert_array_equal(t200.thrust(pwm, 25.0), t200.thrust(pwm, 20.0))
    with pytest.raises(ValueError):
        t200.thrust(pwm, float("nan"))


def test_thrust_is_vectorised_over_any_shape(t200):
    pwm = np.full((3, 4, 8), 1700.0)
    assert t200.thrust(pwm, 15.0).shape == (3, 4, 8)
    assert t200.pwm(np.zeros((2, 8)), 15.0).shape == (2, 8)
    assert np.ndim(t200.thrust(1700.0, 15.0)) == 0


@pytest.mark.parametrize(
    "voltage, band", [(12.0, (1464.0, 1536.0)), (16.0, (1472.0, 1528.0)), (14.8, (1472.0, 1528.0))]
)
def test_dead_band(t200, voltage, band):
    assert t200.dead_band(voltage) == band
    low, high = band
    assert np.all(t200.thrust(np.linspace(low, high, 101), voltage) == 0.0)
    assert t200.thrust(low - 0.5, voltage) < 0 < t200.thrust(high + 0.5, voltage)
    assert t200.pwm(0.0, voltage) == 1500.0


@pytest.mark.parametrize("voltage", VOLTAGES)
def test_tiny_thrust_maps_to_dead_band_edge(t200, voltage):
    low, high = t200.dead_band(voltage)
    for tiny in (1e-12, 1e-6, 1e-3):
        up, down = t200.pwm(tiny, voltage), t200.pwm(-tiny, voltage)
        assert high <= up < high + 0.05
        assert low - 0.05 < down <= low
        assert t200.thrust(up, voltage) > 0 > t200.thrust(down, voltage)


@pytest.mark.parametrize("voltage", VOLTAGES)
def test_thrust_of_pwm_round_trip(t200, voltage):
    f = np.linspace(-t200.max_reverse(voltage), t200.max_forward(voltage), 4001)
    pwm = t200.pwm(f, voltage)
    assert np.all((pwm >= 1100) & (pwm <= 1900))
    np.testing.assert_allclose(t200.thrust(pwm, voltage), f, atol=1e-9)
    low, high = t200.dead_band(voltage)
    assert not np.any((pwm > low) & (pwm < high))


@pytest.mark.parametrize("voltage", VOLTAGES)
def test_pwm_of_thrust_round_trip(t200, voltage):
    low, high = t200.dead_band(voltage)
    p = np.linspace(1100, 1900, 3201)
    p = p[(p < low) | (p > high)]
    back = t200.pwm(t200.thrust(p, voltage), voltage)
    in_plateau = np.zeros_like(p, dtype=bool)
    for v, near, far in PLATEAUS:
        if v == voltage:
            run = (p >= min(near, far)) & (p <= max(near, far))
            np.testing.assert_allclose(back[run], near)
            in_plateau |= run
    np.testing.assert_allclose(back[~in_plateau], p[~in_plateau], atol=1e-9)


def test_pwm_saturates_and_rejects_nan(t200):
    assert t200.pwm(1e3, 16.0) == 1900.0
    assert t200.pwm(-1e3, 16.0) == 1100.0
    assert t200.pwm(-1e3, 12.0) == 1104.0   # 1100 and 1104 give the same (corrected) thrust
    with pytest.raises(ValueError):
        t200.pwm(np.array([1.0, np.nan]), 16.0)


@pytest.mark.parametrize("voltage", VOLTAGES)
def test_limits_and_current(t200, voltage):
    fwd, rev = t200.max_forward(voltage), t200.max_reverse(voltage)
    assert t200.thrust(1900, voltage) == fwd and t200.thrust(1100, voltage) == -rev
    assert 0.74 < rev / fwd < 0.80
    assert t200.current(1500, voltage) == 0.0
    assert t200.current(1900, voltage) > t200.current(1700, voltage) > 0


def test_max_thrust_grows_with_voltage(t200):
    v = np.linspace(10, 20, 41)
    assert np.all(np.diff([t200.max_forward(x) for x in v]) > 0)
    assert np.all(np.diff([t200.max_reverse(x) for x in v]) > 0)
    assert t200.max_forward(16.0) == pytest.approx(51.4362)


def test_eight_thruster_helpers(t200):
    f = np.array([[-20.0, -5.0, 0.0, 1e-4, 3.0, 10.0, 30.0, 45.0]] * 3)
    pwm = thrusts_to_pwms(f, 15.6)
    assert pwm.shape == (3, 8) and pwm[0, 2] == 1500.0
    np.testing.assert_allclose(pwms_to_thrusts(pwm, 15.6), f, atol=1e-9)
    np.testing.assert_array_equal(pwms_to_thrusts(pwm, 15.6, t200), t200.thrust(pwm, 15.6))


def test_bad_data_rejected():
    pwm = np.array([1400.0, 1500.0, 1600.0])
    with pytest.raises(ValueError):   # forward force below 1500
        ThrusterMap([12.0, 16.0], pwm, [[1.0, 0.0, 1.0], [-1.0, 0.0, 1.0]], np.zeros((2, 3)))
    with pytest.raises(ValueError):   # no dead band at 1500
        ThrusterMap([12.0, 16.0], pwm, [[-1.0, 0.5, 1.0], [-1.0, 0.0, 1.0]], np.zeros((2, 3)))


# ---- allocator -----------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def allocator(vehicle):
    return Allocator.for_vehicle(vehicle, 16.0)


def _scaled_pinv_residual(alloc: Allocator, tau: np.ndarray) -> float:
    """Residual norm of the direction-keeping alternative: the largest s <= 1 with B+ (s tau) inside the box."""
    f = alloc.pinv @ tau
    limit = np.where(f > 0, alloc.f_max, alloc.f_min)
    ratios = np.divide(limit, f, out=np.full_like(f, np.inf), where=f != 0)
    s = min(1.0, ratios.min())
    return float(np.linalg.norm((1 - s) * tau))


def test_allocator_limits_from_t200(allocator, t200):
    np.testing.assert_array_equal(allocator.f_max, t200.max_forward(16.0))
    np.testing.assert_array_equal(allocator.f_min, -t200.max_reverse(16.0))


def test_feasible_wrench_is_exact_and_minimum_norm(allocator, B):
    tau = np.array([20.0, -8.0, 15.0, 0.5, -1.0, 3.0])
    f, info = allocator.thrusts(tau)
    np.testing.assert_allclose(B @ f, tau, atol=1e-9)
    np.testing.assert_allclose(f, np.linalg.pinv(B) @ tau, atol=1e-12)
    assert not info.saturated and info.residual_norm < 1e-9
    np.testing.assert_allclose(info.wrench, tau, atol=1e-9)
    np.testing.assert_allclose(allocator.wrench(f), B @ f)


def test_achievable_wrench_outside_pinv_box_is_still_exact(allocator, B):
    # Three verticals at full forward thrust: pinv removes the null-space part and asks 1.25x of thruster 5.
    fmax = allocator.f_max[0]
    tau = B @ np.array([0, 0, 0, 0, fmax, fmax, fmax, 0.0])
    assert np.any(allocator.pinv @ tau > allocator.f_max)
    f, info = allocator.thrusts(tau)
    assert info.saturated
    assert np.all((f >= allocator.f_min) & (f <= allocator.f_max))
    assert info.residual_norm < 1e-6


@pytest.mark.parametrize(
    "tau",
    [
        [150.0, 0, 60.0, 0, 0, 10.0],
        [0, 160.0, -100.0, 0, 0, 0],
        [-90.0, 40.0, 0, 5.0, -8.0, -25.0],
        [0, 0, 250.0, 0, 0, 0],
    ],
)
def test_infeasible_wrench_respects_limits_and_beats_scaling(allocator, tau):
    tau = np.array(tau)
    f, info = allocator.thrusts(tau)
    assert info.saturated
    assert np.all(f >= allocator.f_min) and np.all(f <= allocator.f_max)
    np.testing.assert_allclose(info.wrench, allocator.wrench(f), atol=1e-12)
    np.testing.assert_allclose(info.residual, tau - info.wrench, atol=1e-12)
    assert info.residual_norm > 1e-3
    assert info.residual_norm <= _scaled_pinv_residual(allocator, tau) + 1e-9


def test_weights_protect_an_axis(vehicle):
    tau = np.array([150.0, 0, 60.0, 0, 0, 10.0])   # more surge than the horizontals can give, plus yaw
    plain = Allocator.for_vehicle(vehicle, 16.0)
    yaw_first = Allocator.for_vehicle(vehicle, 16.0, weights=[1, 1, 1, 1, 1, 100])
    _, info_plain = plain.thrusts(tau)
    _, info_yaw = yaw_first.thrusts(tau)
    assert abs(info_yaw.residual[N]) < 0.05 < abs(info_plain.residual[N])
    assert abs(info_yaw.residual[X]) > abs(info_plain.residual[X])


def test_batch_matches_single(allocator):
    taus = np.array([[20.0, -8.0, 15.0, 0.5, -1.0, 3.0], [150.0, 0, 60.0, 0, 0, 10.0], np.zeros(6)])
    f, info = allocator.thrusts(taus)
    assert f.shape == (3, 8) and info.wrench.shape == (3, 6) and info.residual_norm.shape == (3,)
    np.testing.assert_array_equal(info.saturated, [False, True, False])
    for i, tau in enumerate(taus):
        f_i, info_i = allocator.thrusts(tau)
        np.testing.assert_allclose(f[i], f_i, atol=1e-12)
        assert info.residual_norm[i] == pytest.approx(info_i.residual_norm, abs=1e-12)


def test_allocate_function(B, allocator):
    tau = np.array([150.0, 0, 60.0, 0, 0, 10.0])
    f, info = allocate(B, tau, allocator.f_min, allocator.f_max)
    np.testing.assert_allclose(f, allocator.thrusts(tau)[0], atol=1e-12)
    with pytest.raises(ValueError):
        allocate(B, tau, allocator.f_max, allocator.f_min)   # limits swapped
    with pytest.raises(ValueError):
        allocate(B[:, :5], tau, -np.ones(5), np.ones(5))     # rank 5
