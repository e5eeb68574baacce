"""The 6-DOF model: Property 1, power balance, kinematics, restoring forces, and kernel == matrix form."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import random_states
from scipy.spatial.transform import Rotation

from rov_mav.model import dynamics, kernel


def trig(eta):
    """cos and sin of roll, pitch, yaw, in the order the kernel takes them."""
    return (np.cos(eta[3]), np.sin(eta[3]), np.cos(eta[4]), np.sin(eta[4]), np.cos(eta[5]), np.sin(eta[5]))


def test_rotation_matches_scipy_zyx(rng):
    eta, _ = random_states(rng, 50)
    expected = Rotation.from_euler("ZYX", eta[:, [5, 4, 3]]).as_matrix()
    np.testing.assert_allclose(dynamics.rotation(eta), expected, atol=1e-12)


def test_one_attitude_multiplied_out_is_the_batched_product(rng):
    """rotation() of one pose (its closed form, attitude_rotation) equals the same pose's row of a batch."""
    eta = rng.uniform(-np.pi, np.pi, (200, 6))
    np.testing.assert_allclose(np.array([dynamics.rotation(e) for e in eta]), dynamics.rotation(eta), atol=1e-14)
    np.testing.assert_allclose(dynamics.attitude_rotation(*eta[0, 3:]), dynamics.rotation(eta[:1])[0], atol=1e-14)


def test_printed_eq_2_3_is_not_a_rotation():
    """ERRATA 1: the printed J_t (rows 2 and 3 misprinted) is not orthonormal; R is."""
    phi, th, psi = 0.3, -0.4, 1.1
    s, c = np.sin, np.cos
    printed = np.array([
        [c(psi) * c(th), -s(psi) * c(phi) + c(psi) * s(th) * s(phi), s(psi) * s(th) + c(psi) * c(phi) * s(th)],
        [s(psi) * c(th), c(psi) * s(th) + s(phi) * s(th) * s(psi), -c(psi) * s(th) + s(th) * s(psi) * c(phi)],
        [-s(th), c(th) * s(phi), c(th) * s(phi)]])
    R = dynamics.rotation(np.array([0, 0, 0, phi, th, psi]))
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    assert np.abs(printed @ printed.T - np.eye(3)).max() > 0.1


def test_kernel_rotation_matches_matrix_form(rng):
    eta, _ = random_states(rng, 20)
    for e in eta:
        R = np.reshape(kernel.rotation(*trig(e)), (3, 3))
        np.testing.assert_allclose(R, dynamics.rotation(e), atol=1e-14)


def test_mass_matrix_symmetric_positive_definite(vehicle):
    M = vehicle.mass_matrix
    np.testing.assert_allclose(M, M.T)
    assert np.linalg.eigvalsh(M).min() > 0


def test_coriolis_skew_symmetric_and_power_free(vehicle, rng):
    _, nu = random_states(rng, 100)
    C = dynamics.coriolis(vehicle.mass_matrix, nu)
    np.testing.assert_allclose(C, -np.swapaxes(C, -1, -2), atol=1e-12)
    np.testing.assert_allclose(np.einsum("ni,nij,nj->n", nu, C, nu), 0.0, atol=1e-12)


def test_coriolis_skew_with_offset_cg_and_products(vehicle, rng):
    """m2c keeps C = -C^T for a full mass matrix too (off-centre CG, inertia products)."""
    A = rng.normal(size=(6, 6))
    M = A @ A.T + 6 * np.eye(6)
    _, nu = random_states(rng, 10)
    C = dynamics.coriolis(M, nu)
    np.testing.assert_allclose(C, -np.swapaxes(C, -1, -2), atol=1e-12)


def test_damping_positive_definite(vehicle, rng):
    _, nu = random_states(rng, 50)
    D = dynamics.damping(vehicle, nu)
    np.testing.assert_allclose(D, np.swapaxes(D, -1, -2))
    # Y_v, K_p, N_r linear terms are 0: D is positive definite for nu with no zero component.
    assert (np.linalg.eigvalsh(D).min(axis=-1) > 0).all()
    assert (np.einsum("ni,nij,nj->n", nu, D, nu) > 0).all()


def test_jacobian_dot_against_finite_difference(rng):
    eta, nu = random_states(rng, 20)
    eta_dot = np.einsum("nij,nj->ni", dynamics.jacobian(eta), nu)
    h = 1e-6
    fd = (dynamics.jacobian(eta + h * eta_dot) - dynamics.jacobian(eta - h * eta_dot)) / (2 * h)
    np.testing.assert_allclose(dynamics.jacobian_dot(eta, eta_dot), fd, atol=1e-6)


def test_kernel_jacobian_dot_nu_matches_matrix_form(rng):
    eta, nu = random_states(rng, 20)
    for e, n in zip(eta, nu):
        cphi, sphi, cth, sth, cpsi, spsi = trig(e)
        R = kernel.rotation(cphi, sphi, cth, sth, cpsi, spsi)
        rates = kernel.euler_rates(cphi, sphi, cth, sth, *n[3:])
        eta_dot = np.concatenate([np.reshape(R, (3, 3)) @ n[:3], rates])
        np.testing.assert_allclose(eta_dot, dynamics.jacobian(e) @ n, atol=1e-12)
        A = kernel.jacobian_dot_nu(R, cphi, sphi, cth, sth, rates[0], rates[1], *n)
        np.testing.assert_allclose(A, dynamics.jacobian_dot(e, eta_dot) @ n, atol=1e-9)


def test_restoring_matches_appendix_formula(vehicle, rng):
    """Kernel's expanded Appendix I.4 rows == the wrench built from forces at r_g and r_b."""
    eta, _ = random_states(rng, 30)
    for e in eta:
        g = kernel.restoring(vehicle.packed(), *trig(e)[:4])
        np.testing.assert_allclose(g, dynamics.restoring(vehicle, e), atol=1e-12)


def test_neutral_buoyancy_and_righting_moment_signs(vehicle):
    assert vehicle.weight == pytest.approx(vehicle.buoyancy)       # rho = 1000: neutral
    level = dynamics.restoring(vehicle, np.zeros(6))
    np.testing.assert_allclose(level, 0.0, atol=1e-12)
    rolled = dynamics.restoring(vehicle, np.array([0, 0, 0, 0.2, 0, 0]))
    pitched = dynamics.restoring(vehicle, np.array([0, 0, 0, 0, 0.2, 0]))
    # The restoring term enters as -g: a positive roll/pitch gets a negative (righting) moment.
    assert -rolled[3] < 0 and -pitched[4] < 0
    salty = dataclasses.replace(vehicle, water_density=1025.0)
    assert -dynamics.restoring(salty, np.zeros(6))[2] < 0            # positively buoyant: pushed up (-z)


def test_kernel_state_derivative_matches_matrix_form(vehicle, rng):
    eta, nu = random_states(rng, 30)
    tau = rng.normal(0, 20, (30, 6))
    p = vehicle.packed()
    dx = np.zeros(12)
    for e, n, t in zip(eta, nu, tau):
        kernel.state_derivative(p, np.concatenate([e, n]), t, np.zeros(3), dx)
        np.testing.assert_allclose(dx[:6], dynamics.jacobian(e) @ n, atol=1e-12)
        np.testing.assert_allclose(dx[6:], dynamics.acceleration(vehicle, e, n, t), rtol=1e-10, atol=1e-9)


@pytest.mark.parametrize("rate_scale", [1.0, 20.0])
def test_rk4_step_is_classic_rk4_on_the_state_derivative(vehicle, rng, rate_scale):
    """rk4_step turns the attitude's sines and cosines from stage to stage instead of calling them again: it equals
    the textbook RK4 over state_derivative to rounding, for the small turns of a flight (series) and for body rates
    of 20 rad/s (library calls)."""
    p, env = vehicle.packed(), np.zeros(kernel.E_SIZE)
    env[kernel.E_CURRENT:kernel.E_CURRENT + 3] = [0.2, -0.1, 0.05]
    eta, nu = random_states(rng, 20)
    h, ws = 0.01, np.zeros(80)

    def f(x, tau):
        dx = np.zeros(12)
        kernel.state_derivative(p, x, tau, env[kernel.E_CURRENT:kernel.E_CURRENT + 3], dx)
        return dx

    for e, n, tau in zip(eta, nu * rate_scale, rng.normal(0, 20, (20, 6))):
        x = np.concatenate([e, n])
        k1 = f(x, tau)
        k2 = f(x + h / 2 * k1, tau)
        k3 = f(x + h / 2 * k2, tau)
        k4 = f(x + h * k3, tau)
        expected = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        kernel.rk4_step(p, env, x, tau, 0.0, h, ws)
        np.testing.assert_allclose(x, expected, rtol=1e-13, atol=1e-13)


def test_rk4_step_carries_the_attitude_trig_without_drift(vehicle):
    """A tumbling, turning vehicle over 6,000 steps: rk4_step carrying its sines and cosines from step to step
    (refreshed every TRIG_REFRESH) flies the run that computing them afresh at every step (a zeroed workspace)
    flies, to 1e-11."""
    p, env = vehicle.packed(), np.zeros(kernel.E_SIZE)
    tau = np.array([20.0, -5.0, 10.0, 1.5, -1.0, 2.0])
    carried, fresh = (np.concatenate([[0, 0, 0, 0.3, -0.2, 3.0], [0.2, 0, 0, 0.5, 0.4, 0.8]]) for _ in range(2))
    ws = np.zeros(80)
    for k in range(6000):
        kernel.rk4_step(p, env, carried, tau, k * 0.01, 0.01, ws)
        kernel.rk4_step(p, env, fresh, tau, k * 0.01, 0.01, np.zeros(80))
    assert np.ptp(fresh[3:6]) > 1.0    # it turned
    np.testing.assert_allclose(carried, fresh, rtol=0, atol=1e-11)


def test_rk4_converges_at_fourth_order(vehicle):
    """Halving the step cuts the error ~16x; the 10 ms step is converged well below a millimetre."""
    p, env = vehicle.packed(), np.zeros(kernel.E_SIZE)
    tau = np.array([30.0, -10.0, 15.0, 0.5, -0.3, 1.0])

    def run(h, t_end=2.0):
        x = np.concatenate([np.zeros(6), [0.2, 0, 0, 0.1, 0, 0.3]])
        ws = np.zeros(80)
        for k in range(int(round(t_end / h))):
            kernel.rk4_step(p, env, x, tau, k * h, h, ws)
        return x

    exact = run(0.000625)
    errors = [np.abs(run(h) - exact).max() for h in (0.04, 0.02, 0.01)]
    assert 10 < errors[0] / errors[1] < 22 and 10 < errors[1] / errors[2] < 22
    assert errors[2] < 1e-6


def test_no_thrust_neutral_vehicle_stays_put(vehicle):
    p, env = vehicle.packed(), np.zeros(kernel.E_SIZE)
    x = np.concatenate([[1.0, 2.0, 3.0, 0, 0, 0.5], np.zeros(6)])
    ws = np.zeros(80)
    for k in range(1000):
        kernel.rk4_step(p, env, x, np.zeros(6), k * 0.01, 0.01, ws)
    np.testing.assert_allclose(x, [1.0, 2.0, 3.0, 0, 0, 0.5] + [0] * 6, atol=1e-12)


def test_surge_terminal_speed_balances_drag(vehicle):
    """Constant surge force F settles where F = (X_u + X_u|u| u) u."""
    p, env = vehicle.packed(), np.zeros(kernel.E_SIZE)
    x, ws = np.zeros(12), np.zeros(80)
    force = 20.0
    for k in range(3000):
        kernel.rk4_step(p, env, x, np.array([force, 0, 0, 0, 0, 0]), k * 0.01, 0.01, ws)
    xu, xuu = vehicle.linear_damping[0], vehicle.quadratic_damping[0]
    expected = (-xu + np.sqrt(xu**2 + 4 * xuu * force)) / (2 * xuu)
    assert x[6] == pytest.approx(expected, rel=1e-6)


def test_free_motion_conserves_inertial_momentum_and_energy(vehicle):
    """With no damping and no restoring force (Kirchhoff's equations), the momentum R (M11 nu1 + M12 nu2) is constant
    in the NED frame and the kinetic energy 1/2 nu^T M nu is constant. Energy alone holds for either sign of C
    (nu^T C nu = 0); the momentum pins the m2c sign convention of ERRATA 5 (the printed C_a has the other one)."""
    ideal = dataclasses.replace(vehicle, linear_damping=np.zeros(6), quadratic_damping=np.zeros(6),
                                center_of_buoyancy=np.zeros(3), center_of_gravity=np.zeros(3))
    p, env, M = ideal.packed(), np.zeros(kernel.E_SIZE), ideal.mass_matrix
    x = np.concatenate([[0, 0, 0, 0.1, -0.2, 0.3], [0.4, -0.2, 0.3, 0.5, -0.4, 0.6]])
    ws = np.zeros(80)

    def momentum_and_energy(x):
        R = dynamics.rotation(x[:6])
        return R @ (M[:3] @ x[6:]), 0.5 * x[6:] @ M @ x[6:]

    p0, e0 = momentum_and_energy(x)
    for k in range(2000):
        kernel.rk4_step(p, env, x, np.zeros(6), k * 0.002, 0.002, ws)
    p1, e1 = momentum_and_energy(x)
    np.testing.assert_allclose(p1, p0, atol=1e-8)
    assert e1 == pytest.approx(e0, rel=1e-8)


def test_body_velocity_is_the_jacobians_inverse():
    """nu = body_velocity(eta, eta_dot) gives back eta_dot through Eq. 2.1, for poses away from theta = 90 deg."""
    rng = np.random.default_rng(4)
    eta = rng.uniform(-1.2, 1.2, (50, 6))
    eta_dot = rng.normal(size=(50, 6))
    nu = dynamics.body_velocity(eta, eta_dot)
    np.testing.assert_allclose(np.einsum("nij,nj->ni", dynamics.jacobian(eta), nu), eta_dot, atol=1e-10)
