"""The report's law: model-based backstepping with a disturbance estimate (baseline, constant, fuzzy), compiled.

Sources: the report's Eqs. 2.13-2.17 as corrected by ERRATA 2 (the law) and Eq. 2.22 as corrected by ERRATA 3
(the adaptation; both in docs/errata.md); Eq. 2.29 and Appendix III (the fuzzy rates). `rov_mav.control.law` holds the
readable matrix
form the tests hold this to. Parameter vector: [k1 (6) | k2 (6) | constant_gamma (6) | d_max (6)]; state: the
estimate tau_hat (6).
"""

from __future__ import annotations

from rov_mav.model.kernel import (
    P_MINV,
    body_from_earth,
    compiled,
    inlined,
    coriolis_times_nu,
    damping_times_nu,
    mass_row,
    restoring,
    state_kinematics,
    tracking_error,
)

PARAMETERS = (("k1", 6), ("k2", 6), ("constant_gamma", 6), ("d_max", 6))
TUNED = ("k1", "k2")
BOUNDS = {"k1": (0.1, 10.0), "k2": (0.1, 10.0)}   # ERRATA: the report's optimum spans 0.8-10
STATE_SIZE = 6

# Rate schedules of the disturbance adaptation (also the controller kinds of the family).
SCHEDULE_NONE = 0       # baseline backstepping: tau_hat = 0
SCHEDULE_CONSTANT = 1   # constant Gamma
SCHEDULE_FUZZY = 2      # Mamdani FIS, tabulated (rov_mav.control.fuzzy)


@inlined
def control_law(m, k1, k2, eta, trig, nu, ref, tau_hat, tau, s, grad):
    """The corrected backstepping law (ERRATA 2, Eq. 2.17) and the adaptation direction (ERRATA 3, Eq. 2.22).

    tau  = M J^-1 (eta_dd_d - k1 e_dot - J_dot nu - k2 s) + C(nu) nu + D(nu) nu + g(eta) - tau_hat
    s    = e_dot + k1 e (Eq. 2.14), e = eta - eta_d with angle errors wrapped (Eq. 2.13)
    grad = (J M^-1)^T s = M^-T J^T s, so that d(tau_hat)/dt = Gamma grad.
    trig: attitude_trig(eta); ref: (18,) = [eta_d, eta_dot_d, eta_ddot_d]. Writes tau, s, grad (6,)."""
    cphi, sphi, cth, sth, R, eta_dot, A = state_kinematics(trig, nu)
    u, v, w, p, q, r = nu[0], nu[1], nu[2], nu[3], nu[4], nu[5]
    a = grad    # scratch for the virtual acceleration; grad is written only after a is consumed
    for i in range(6):
        e, e_dot = tracking_error(eta, eta_dot, ref, i)
        s[i] = e_dot + k1[i] * e
        a[i] = ref[12 + i] - k1[i] * e_dot - A[i] - k2[i] * s[i]
    wv0, wv1, wv2, wv3, wv4, wv5 = body_from_earth(cphi, sphi, cth, sth, R, a)
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


@inlined
def adaptation_rates(schedule, grad, gamma_const, table, table_scale, gamma):
    """Gamma per body DOF: constant, or the tabulated Mamdani FIS of |grad_i| (Eq. 2.29), table_scale (6,) its
    samples per unit of |grad_i|; writes gamma (6,)."""
    last = table.shape[1] - 1
    for i in range(6):
        if schedule == SCHEDULE_CONSTANT:
            gamma[i] = gamma_const[i]
        elif schedule == SCHEDULE_FUZZY:
            pos = min(abs(grad[i]) * table_scale[i], last)
            k = min(int(pos), last - 1)
            frac = pos - k
            gamma[i] = table[i, k] * (1.0 - frac) + table[i, k + 1] * frac
        else:
            gamma[i] = 0.0


@inlined
def adapt(schedule, grad, gamma, d_max, dt, tau_hat):
    """One explicit step of d(tau_hat)/dt = Gamma (J M^-1)^T s (ERRATA 3), projected onto |tau_hat_i| <= d_max_i
    (Assumption 2). Baseline (no schedule) keeps tau_hat = 0."""
    for i in range(6):
        if schedule == SCHEDULE_NONE:
            tau_hat[i] = 0.0
        else:
            value = tau_hat[i] + dt * gamma[i] * grad[i]
            tau_hat[i] = min(max(value, -d_max[i]), d_max[i])


@inlined
def step(schedule, m, params, table, table_scale, eta, trig, nu, ref, dt, state, tau, tau_hat, s, grad, gamma):
    """One tick: tau from the law with the current estimate (state[0:6]), then the estimate advanced by dt.

    Writes tau, tau_hat (the estimate after the update), s, grad, gamma (6,) each."""
    estimate = state[0:6]
    control_law(m, params[0:6], params[6:12], eta, trig, nu, ref, estimate, tau, s, grad)
    adaptation_rates(schedule, grad, params[12:18], table, table_scale, gamma)
    adapt(schedule, grad, gamma, params[18:24], dt, estimate)
    for i in range(6):
        tau_hat[i] = estimate[i]
