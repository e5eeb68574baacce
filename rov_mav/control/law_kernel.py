"""The compiled control law and disturbance adaptation (Numba, cached), one tick at a time.

`controller_step` is the one implementation of the law: the runner calls it tick by tick (`rov_mav.control.controller`)
and the offline closed loop calls it for a whole swarm (`rov_mav.offline.loop_kernel`). `rov_mav.control.law` holds
the readable matrix form that the tests hold it to.
"""

from __future__ import annotations

import math

from rov_mav.model.kernel import (
    P_MINV,
    compiled,
    coriolis_times_nu,
    damping_times_nu,
    euler_rates,
    jacobian_dot_nu,
    mass_row,
    restoring,
    rotation,
    wrap_angle,
)

# Rate schedules of the disturbance adaptation.
SCHEDULE_NONE = 0       # baseline backstepping: tau_hat = 0
SCHEDULE_CONSTANT = 1   # constant Gamma
SCHEDULE_FUZZY = 2      # Mamdani FIS, tabulated (rov_mav.control.fuzzy)


@compiled
def control_law(m, k1, k2, eta, nu, ref, tau_hat, tau, s, grad):
    """The corrected backstepping law (ERRATA 2, Eq. 2.17) and the adaptation direction (ERRATA 3, Eq. 2.22).

    tau  = M J^-1 (eta_dd_d - k1 e_dot - J_dot nu - k2 s) + C(nu) nu + D(nu) nu + g(eta) - tau_hat
    s    = e_dot + k1 e (Eq. 2.14), e = eta - eta_d with angle errors wrapped (Eq. 2.13)
    grad = (J M^-1)^T s = M^-T J^T s, so that d(tau_hat)/dt = Gamma grad.
    ref: (18,) = [eta_d, eta_dot_d, eta_ddot_d]. Writes tau, s, grad (6,)."""
    cphi, sphi = math.cos(eta[3]), math.sin(eta[3])
    cth, sth = math.cos(eta[4]), math.sin(eta[4])
    cpsi, spsi = math.cos(eta[5]), math.sin(eta[5])
    u, v, w, p, q, r = nu[0], nu[1], nu[2], nu[3], nu[4], nu[5]
    R = rotation(cphi, sphi, cth, sth, cpsi, spsi)
    dphi, dth, dpsi = euler_rates(cphi, sphi, cth, sth, p, q, r)
    eta_dot = (R[0] * u + R[1] * v + R[2] * w, R[3] * u + R[4] * v + R[5] * w,
               R[6] * u + R[7] * v + R[8] * w, dphi, dth, dpsi)
    A = jacobian_dot_nu(R, cphi, sphi, cth, sth, dphi, dth, u, v, w, p, q, r)
    a = grad    # scratch for the virtual acceleration; grad is written only after a is consumed
    for i in range(6):
        e = eta[i] - ref[i]
        if i >= 3:
            e = wrap_angle(e)
        e_dot = eta_dot[i] - ref[6 + i]
        s[i] = e_dot + k1[i] * e
        a[i] = ref[12 + i] - k1[i] * e_dot - A[i] - k2[i] * s[i]
    # wv = J^-1 a: R^T on the translation, T^-1 on the rotation.
    wv0 = R[0] * a[0] + R[3] * a[1] + R[6] * a[2]
    wv1 = R[1] * a[0] + R[4] * a[1] + R[7] * a[2]
    wv2 = R[2] * a[0] + R[5] * a[1] + R[8] * a[2]
    wv3 = a[3] - sth * a[5]
    wv4 = cphi * a[4] + cth * sphi * a[5]
    wv5 = -sphi * a[4] + cth * cphi * a[5]
    c = coriolis_times_nu(m, u, v, w, p, q, r)
    d = damping_times_nu(m, u, v, w, p, q, r)
    g = restoring(m, cphi, sphi, cth, sth)
    for i in range(6):
        tau[i] = mass_row(m, i, wv0, wv1, wv2, wv3, wv4, wv5) + c[i] + d[i] + g[i] - tau_hat[i]
    # grad = M^-T (J^T s), J^T s = [R^T s1 ; T^T s2].
    tth = sth / cth
    j0 = R[0] * s[0] + R[3] * s[1] + R[6] * s[2]
    j1 = R[1] * s[0] + R[4] * s[1] + R[7] * s[2]
    j2 = R[2] * s[0] + R[5] * s[1] + R[8] * s[2]
    j3 = s[3]
    j4 = sphi * tth * s[3] + cphi * s[4] + sphi / cth * s[5]
    j5 = cphi * tth * s[3] - sphi * s[4] + cphi / cth * s[5]
    for i in range(6):
        b = P_MINV + i
        grad[i] = (m[b] * j0 + m[b + 6] * j1 + m[b + 12] * j2 + m[b + 18] * j3 + m[b + 24] * j4
                   + m[b + 30] * j5)


@compiled
def adaptation_rates(schedule, grad, gamma_const, table, table_xmax, gamma):
    """Gamma per body DOF: constant, or the tabulated Mamdani FIS of |grad_i| (Eq. 2.29); writes gamma (6,)."""
    n = table.shape[1]
    for i in range(6):
        if schedule == SCHEDULE_CONSTANT:
            gamma[i] = gamma_const[i]
        elif schedule == SCHEDULE_FUZZY:
            pos = min(abs(grad[i]) / table_xmax[i], 1.0) * (n - 1)
            k = min(int(pos), n - 2)
            frac = pos - k
            gamma[i] = table[i, k] * (1.0 - frac) + table[i, k + 1] * frac
        else:
            gamma[i] = 0.0


@compiled
def adapt(schedule, grad, gamma, d_max, dt, tau_hat):
    """One explicit step of d(tau_hat)/dt = Gamma (J M^-1)^T s (ERRATA 3), projected onto |tau_hat_i| <= d_max_i
    (Assumption 2). Baseline (no schedule) keeps tau_hat = 0."""
    for i in range(6):
        if schedule == SCHEDULE_NONE:
            tau_hat[i] = 0.0
        else:
            value = tau_hat[i] + dt * gamma[i] * grad[i]
            tau_hat[i] = min(max(value, -d_max[i]), d_max[i])


@compiled
def controller_step(m, k1, k2, schedule, gamma_const, table, table_xmax, d_max, eta, nu, ref, dt,
                    tau_hat, tau, s, grad, gamma):
    """One control tick: tau from the law with the current estimate, then the estimate advanced by dt.

    tau_hat is updated in place; tau, s, grad, gamma are written (6,) each."""
    control_law(m, k1, k2, eta, nu, ref, tau_hat, tau, s, grad)
    adaptation_rates(schedule, grad, gamma_const, table, table_xmax, gamma)
    adapt(schedule, grad, gamma, d_max, dt, tau_hat)
