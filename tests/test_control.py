"""The corrected law and adaptation: Lemma 1, the Lyapunov identity, the printed forms failing, projection."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import random_states

from rov_mav.control import backstepping, law
from rov_mav.control.controller import Controller, load_settings
from rov_mav.model import dynamics, kernel

K1 = np.array([10, 1, 5.9, 1.7, 5.8, 0.8])
K2 = np.array([5.2, 10, 1, 5.8, 1.9, 5.5])


def random_references(rng, n):
    eta_d, _ = random_states(rng, n)
    return np.concatenate([eta_d, rng.normal(0, 0.3, (n, 6)), rng.normal(0, 0.2, (n, 6))], axis=1)


def sdot(vehicle, eta, nu, ref, tau, tau_d):
    """ds/dt of the true closed loop: eta_dd = J_dot nu + J nu_dot (Eq. 2.15), nu_dot from Eq. 2.7."""
    J = dynamics.jacobian(eta)
    eta_dot = J @ nu
    nu_dot = dynamics.acceleration(vehicle, eta, nu, tau + tau_d)
    eta_dd = dynamics.jacobian_dot(eta, eta_dot) @ nu + J @ nu_dot
    return eta_dd - ref[12:] + K1 * (eta_dot - ref[6:12])


def test_kernel_law_matches_matrix_form(vehicle, rng):
    eta, nu = random_states(rng, 25)
    refs = random_references(rng, 25)
    tau_hat = rng.normal(0, 2, (25, 6))
    p = vehicle.packed()
    tau, s, grad = np.zeros(6), np.zeros(6), np.zeros(6)
    for i in range(25):
        backstepping.control_law(p, K1, K2, eta[i], kernel.attitude_trig(eta[i]), nu[i], refs[i], tau_hat[i], tau, s,
                                 grad)
        tau_ref, s_ref = law.control_law(vehicle, K1, K2, eta[i], nu[i], refs[i], tau_hat[i])
        np.testing.assert_allclose(tau, tau_ref, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(s, s_ref, atol=1e-12)
        np.testing.assert_allclose(grad, law.adaptation_direction(vehicle, eta[i], s_ref), atol=1e-12)


def test_lemma_1_exact_disturbance_estimate_gives_sdot_minus_k2_s(vehicle, rng):
    eta, nu = random_states(rng, 40)
    refs = random_references(rng, 40)
    tau_d = rng.normal(0, 3, (40, 6))
    for i in range(40):
        tau, s = law.control_law(vehicle, K1, K2, eta[i], nu[i], refs[i], tau_hat=tau_d[i])
        np.testing.assert_allclose(sdot(vehicle, eta[i], nu[i], refs[i], tau, tau_d[i]), -K2 * s, atol=1e-9)


def test_printed_eq_2_17_fails_lemma_1(vehicle, rng):
    """ERRATA 2: with the printed leading factor (J M^-1)^T the identity ds/dt = -k2 s does not hold."""
    eta, nu = random_states(rng, 10)
    refs = random_references(rng, 10)
    worst = 0.0
    for i in range(10):
        _, s = law.control_law(vehicle, K1, K2, eta[i], nu[i], refs[i], np.zeros(6))
        J = dynamics.jacobian(eta[i])
        JMinv = J @ np.linalg.inv(vehicle.mass_matrix)
        eta_dot = J @ nu[i]
        A = dynamics.jacobian_dot(eta[i], eta_dot) @ nu[i]
        CDg = ((dynamics.coriolis(vehicle.mass_matrix, nu[i]) + dynamics.damping(vehicle, nu[i])) @ nu[i]
               + dynamics.restoring(vehicle, eta[i]))
        e_dot = eta_dot - refs[i, 6:12]
        printed = JMinv.T @ (-K1 * e_dot + refs[i, 12:] + JMinv @ CDg - A - K2 * s)
        worst = max(worst, np.abs(sdot(vehicle, eta[i], nu[i], refs[i], printed, np.zeros(6)) + K2 * s).max())
    assert worst > 1.0


def lyapunov_rate(vehicle, eta, nu, ref, tau_d, tau_hat, gamma, direction):
    """dV/dt for V = 1/2 s^T s + 1/2 tau_tilde^T Gamma^-1 tau_tilde, with d(tau_hat)/dt = Gamma direction."""
    tau, s = law.control_law(vehicle, K1, K2, eta, nu, ref, tau_hat)
    tau_tilde = tau_hat - tau_d
    tau_hat_dot = gamma * direction(s)           # d(tau_tilde)/dt = d(tau_hat)/dt for constant tau_d (Eq. 2.27)
    return s @ sdot(vehicle, eta, nu, ref, tau, tau_d) + tau_tilde @ (tau_hat_dot / gamma), s


def test_lyapunov_identity_with_corrected_adaptation(vehicle, rng):
    """ERRATA 3: dV/dt = -s^T k2 s for constant Gamma and tau_d."""
    eta, nu = random_states(rng, 30)
    refs = random_references(rng, 30)
    gamma = np.array([45, 45, 45, 0.45, 0.45, 0.45])
    for i in range(30):
        tau_d, tau_hat = rng.normal(0, 3, 6), rng.normal(0, 3, 6)
        vdot, s = lyapunov_rate(vehicle, eta[i], nu[i], refs[i], tau_d, tau_hat, gamma,
                                lambda s_: law.adaptation_direction(vehicle, eta[i], s_))
        assert vdot == pytest.approx(-s @ (K2 * s), rel=1e-9, abs=1e-9)


def test_printed_eq_2_22_breaks_the_lyapunov_identity(vehicle, rng):
    """The printed Gamma (M^-1 J)^T s leaves a cross term: dV/dt != -s^T k2 s."""
    eta, nu = random_states(rng, 10)
    refs = random_references(rng, 10)
    gamma = np.ones(6)
    Minv = np.linalg.inv(vehicle.mass_matrix)
    worst = 0.0
    for i in range(10):
        tau_d, tau_hat = rng.normal(0, 3, 6), rng.normal(0, 3, 6)
        J = dynamics.jacobian(eta[i])
        vdot, s = lyapunov_rate(vehicle, eta[i], nu[i], refs[i], tau_d, tau_hat, gamma,
                                lambda s_: (Minv @ J).T @ s_)
        worst = max(worst, abs(vdot + s @ (K2 * s)))
    assert worst > 1e-2


def test_estimate_is_projected_onto_d_max(vehicle):
    settings = load_settings("constant")
    controller = Controller(vehicle, settings)
    eta = np.zeros(6)
    ref = np.zeros(18)
    ref[:3] = [50.0, -50.0, 50.0]          # huge error: the estimate is driven hard
    ref[3:6] = [0.3, -0.3, 0.3]
    for _ in range(20000):
        out = controller.step(eta, np.zeros(6), ref, 0.01)
    assert (np.abs(out.tau_hat) <= settings.d_max + 1e-12).all()
    assert (np.abs(out.tau_hat) == pytest.approx(settings.d_max)), "each component should sit on its bound"


def test_baseline_keeps_zero_estimate(vehicle):
    controller = Controller(vehicle, load_settings("baseline"))
    ref = np.zeros(18)
    ref[0] = 1.0
    out = controller.step(np.zeros(6), np.zeros(6), ref, 0.01)
    np.testing.assert_array_equal(out.tau_hat, 0.0)
    np.testing.assert_array_equal(out.gamma, 0.0)
