"""The compiled core: 6-DOF model, control law, adaptation and closed-loop simulation (Numba, cached).

Every path that moves the vehicle model or runs the law goes through these functions: the offline simulator and
the tuner (`simulate_batch`, a whole swarm in one call), the bridge's plant (`rk4_step`) and the runner
(`controller_step`). They work on flat float64 arrays and preallocated workspaces so the inner loop allocates
nothing. `rov_mav.dynamics` and `rov_mav.law` hold the readable matrix forms that the tests hold these to.

Conventions: eta = [x, y, z, phi, theta, psi] (NED, ZYX Euler), nu = [u, v, w, p, q, r] (body FRD).
Packed vehicle vector (see `rov_mav.model.pack_vehicle`): M (36), M^-1 (36), linear damping (6),
quadratic damping (6), W, B, r_g (3), r_b (3).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

P_M = 0
P_MINV = 36
P_DLIN = 72
P_DQUAD = 78
P_W = 84
P_B = 85
P_RG = 86
P_RB = 89
P_SIZE = 92

# Packed environment vector: constant disturbance (6), sinusoid amplitude (6), sinusoid period (1),
# NED current (3), sensor noise std for position, attitude, linear velocity, angular rate (4).
E_DIST = 0
E_AMP = 6
E_PERIOD = 12
E_CURRENT = 13
E_NOISE = 16
E_SIZE = 20

# Rate schedules of the disturbance adaptation.
SCHEDULE_NONE = 0       # baseline backstepping: tau_hat = 0
SCHEDULE_CONSTANT = 1   # constant Gamma
SCHEDULE_FUZZY = 2      # Mamdani FIS, tabulated (rov_mav.fuzzy)

# Limits beyond which a simulated vehicle counts as diverged (Assumption 1 and sanity bounds).
MAX_TILT = 1.4          # rad, |phi|, |theta| (the Euler kinematics are singular at pi/2)
MAX_SPEED = 20.0        # m/s or rad/s, any component of nu
DIVERGED_COST = 1.0e12


@njit(cache=True)
def rotation(phi, theta, psi, R):
    """R(Theta), ZYX body-to-NED rotation (ERRATA 1, Fossen 2021 eq. 2.18); writes R (3, 3)."""
    cphi, sphi = math.cos(phi), math.sin(phi)
    cth, sth = math.cos(theta), math.sin(theta)
    cpsi, spsi = math.cos(psi), math.sin(psi)
    R[0, 0] = cpsi * cth
    R[0, 1] = -spsi * cphi + cpsi * sth * sphi
    R[0, 2] = spsi * sphi + cpsi * cphi * sth
    R[1, 0] = spsi * cth
    R[1, 1] = cpsi * cphi + sphi * sth * spsi
    R[1, 2] = -cpsi * sphi + sth * spsi * cphi
    R[2, 0] = -sth
    R[2, 1] = cth * sphi
    R[2, 2] = cth * cphi


@njit(cache=True)
def euler_rates(phi, theta, w, out):
    """T(Theta) w: Euler-angle rates from body rates w (Eq. 2.4); writes out (3,)."""
    cphi, sphi = math.cos(phi), math.sin(phi)
    cth, tth = math.cos(theta), math.tan(theta)
    out[0] = w[0] + sphi * tth * w[1] + cphi * tth * w[2]
    out[1] = cphi * w[1] - sphi * w[2]
    out[2] = (sphi * w[1] + cphi * w[2]) / cth


@njit(cache=True)
def kinematics(eta, nu, R, eta_dot):
    """eta_dot = J(eta) nu (Eq. 2.1); fills R with R(Theta) on the way."""
    rotation(eta[3], eta[4], eta[5], R)
    for i in range(3):
        eta_dot[i] = R[i, 0] * nu[0] + R[i, 1] * nu[1] + R[i, 2] * nu[2]
    euler_rates(eta[3], eta[4], nu[3:6], eta_dot[3:6])


@njit(cache=True)
def jacobian_dot_nu(eta, nu, R, eta_dot, out):
    """A = J_dot(eta, eta_dot) nu (Eq. 2.15), with R and eta_dot from `kinematics`; writes out (6,).

    Translation: R_dot nu1 = R (omega x nu1). Rotation: T_dot nu2 with T_dot = phi_dot dT/dphi + theta_dot dT/dtheta."""
    p, q, r = nu[3], nu[4], nu[5]
    cx = q * nu[2] - r * nu[1]
    cy = r * nu[0] - p * nu[2]
    cz = p * nu[1] - q * nu[0]
    for i in range(3):
        out[i] = R[i, 0] * cx + R[i, 1] * cy + R[i, 2] * cz
    phi, theta = eta[3], eta[4]
    dphi, dth = eta_dot[3], eta_dot[4]
    cphi, sphi = math.cos(phi), math.sin(phi)
    cth, sth = math.cos(theta), math.sin(theta)
    tth = sth / cth
    sec2 = 1.0 / (cth * cth)
    out[3] = dphi * (cphi * tth * q - sphi * tth * r) + dth * sec2 * (sphi * q + cphi * r)
    out[4] = dphi * (-sphi * q - cphi * r)
    out[5] = dphi * (cphi * q - sphi * r) / cth + dth * sth * sec2 * (sphi * q + cphi * r)


@njit(cache=True)
def coriolis_times_nu(p, nu, out):
    """C(nu) nu with C built from M by Fossen's m2c (ERRATA 5); writes out (6,).

    C = [[0, -S(a)], [-S(a), -S(b)]], a = M11 nu1 + M12 nu2, b = M21 nu1 + M22 nu2, S(x)y = x cross y."""
    a = np.empty(3)
    b = np.empty(3)
    for i in range(3):
        ai = 0.0
        bi = 0.0
        for j in range(6):
            ai += p[P_M + 6 * i + j] * nu[j]
            bi += p[P_M + 6 * (i + 3) + j] * nu[j]
        a[i] = ai
        b[i] = bi
    u, v, w, pp, q, r = nu[0], nu[1], nu[2], nu[3], nu[4], nu[5]
    out[0] = -(a[1] * r - a[2] * q)
    out[1] = -(a[2] * pp - a[0] * r)
    out[2] = -(a[0] * q - a[1] * pp)
    out[3] = -(a[1] * w - a[2] * v) - (b[1] * r - b[2] * q)
    out[4] = -(a[2] * u - a[0] * w) - (b[2] * pp - b[0] * r)
    out[5] = -(a[0] * v - a[1] * u) - (b[0] * q - b[1] * pp)


@njit(cache=True)
def damping_times_nu(p, nu, out):
    """D(nu) nu = (D_l + D_nl(|nu|)) nu (Appendix I.3, positive magnitudes); writes out (6,)."""
    for i in range(6):
        out[i] = (p[P_DLIN + i] + p[P_DQUAD + i] * abs(nu[i])) * nu[i]


@njit(cache=True)
def restoring(p, eta, out):
    """g(eta), gravity and buoyancy (Appendix I.4); writes out (6,)."""
    W, B = p[P_W], p[P_B]
    xg, yg, zg = p[P_RG], p[P_RG + 1], p[P_RG + 2]
    xb, yb, zb = p[P_RB], p[P_RB + 1], p[P_RB + 2]
    cphi, sphi = math.cos(eta[3]), math.sin(eta[3])
    cth, sth = math.cos(eta[4]), math.sin(eta[4])
    out[0] = (W - B) * sth
    out[1] = -(W - B) * cth * sphi
    out[2] = -(W - B) * cth * cphi
    out[3] = -(yg * W - yb * B) * cth * cphi + (zg * W - zb * B) * cth * sphi
    out[4] = (zg * W - zb * B) * sth + (xg * W - xb * B) * cth * cphi
    out[5] = -(xg * W - xb * B) * cth * sphi - (yg * W - yb * B) * sth


@njit(cache=True)
def state_derivative(p, x, tau, current_ned, dx, ws):
    """d/dt [eta; nu] for the plant (Eqs. 2.1, 2.7): M nu_dot = tau - C(nu) nu - D(nu_r) nu_r - g(eta).

    `tau` is the total body wrench (control + disturbance). A water current enters through the relative velocity
    nu_r = nu - [R^T v_c; 0] in the damping. x, dx: (12,); ws: workspace (40,)."""
    eta = x[0:6]
    nu = x[6:12]
    R = ws[0:9].reshape((3, 3))
    cnu = ws[9:15]
    dnu = ws[15:21]
    gvec = ws[21:27]
    nu_r = ws[27:33]
    kinematics(eta, nu, R, dx[0:6])
    for i in range(3):
        nu_r[i] = nu[i] - (R[0, i] * current_ned[0] + R[1, i] * current_ned[1] + R[2, i] * current_ned[2])
        nu_r[i + 3] = nu[i + 3]
    coriolis_times_nu(p, nu, cnu)
    damping_times_nu(p, nu_r, dnu)
    restoring(p, eta, gvec)
    for i in range(6):
        acc = 0.0
        for j in range(6):
            acc += p[P_MINV + 6 * i + j] * (tau[j] - cnu[j] - dnu[j] - gvec[j])
        dx[6 + i] = acc


@njit(cache=True)
def disturbance(env, t, out):
    """tau_d(t): constant plus a sinusoid per DOF (body frame, N and N m); writes out (6,)."""
    period = env[E_PERIOD]
    phase = math.sin(2.0 * math.pi * t / period) if period > 0.0 else 0.0
    for i in range(6):
        out[i] = env[E_DIST + i] + env[E_AMP + i] * phase


@njit(cache=True)
def rk4_step(p, env, x, tau, t, h, ws):
    """Advance the plant state x (12,) in place by h seconds with the control wrench tau held (classic RK4).

    The disturbance tau_d(t) is evaluated at each stage. ws: workspace (128,)."""
    k1 = ws[0:12]
    k2 = ws[12:24]
    k3 = ws[24:36]
    k4 = ws[36:48]
    xs = ws[48:60]
    total = ws[60:66]
    dist = ws[66:72]
    inner = ws[72:112]
    current = env[E_CURRENT:E_CURRENT + 3]
    for stage in range(4):
        ts = t if stage == 0 else (t + h if stage == 3 else t + 0.5 * h)
        disturbance(env, ts, dist)
        for i in range(6):
            total[i] = tau[i] + dist[i]
        if stage == 0:
            state_derivative(p, x, total, current, k1, inner)
        elif stage == 1:
            for i in range(12):
                xs[i] = x[i] + 0.5 * h * k1[i]
            state_derivative(p, xs, total, current, k2, inner)
        elif stage == 2:
            for i in range(12):
                xs[i] = x[i] + 0.5 * h * k2[i]
            state_derivative(p, xs, total, current, k3, inner)
        else:
            for i in range(12):
                xs[i] = x[i] + h * k3[i]
            state_derivative(p, xs, total, current, k4, inner)
    for i in range(12):
        x[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])


@njit(cache=True)
def wrap_angle(a):
    """Wrap an angle to [-pi, pi)."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi


@njit(cache=True)
def control_law(p, k1, k2, eta, nu, ref, tau_hat, tau, s, grad, ws):
    """The corrected backstepping law (ERRATA 2, Eq. 2.17) and the adaptation direction (ERRATA 3, Eq. 2.22).

    tau  = M J^-1 (eta_dd_d - k1 e_dot - J_dot nu - k2 s) + C(nu) nu + D(nu) nu + g(eta) - tau_hat
    s    = e_dot + k1 e (Eq. 2.14), e = eta - eta_d with angle errors wrapped (Eq. 2.13)
    grad = (J M^-1)^T s = M^-T J^T s, so that d(tau_hat)/dt = Gamma grad.
    ref: (18,) = [eta_d, eta_dot_d, eta_ddot_d]. Writes tau, s, grad (6,); ws: workspace (64,)."""
    R = ws[0:9].reshape((3, 3))
    eta_dot = ws[9:15]
    A = ws[15:21]
    a = ws[21:27]
    w = ws[27:33]
    cnu = ws[33:39]
    dnu = ws[39:45]
    gvec = ws[45:51]
    jts = ws[51:57]
    kinematics(eta, nu, R, eta_dot)
    jacobian_dot_nu(eta, nu, R, eta_dot, A)
    for i in range(6):
        e = eta[i] - ref[i]
        if i >= 3:
            e = wrap_angle(e)
        e_dot = eta_dot[i] - ref[6 + i]
        s[i] = e_dot + k1[i] * e
        a[i] = ref[12 + i] - k1[i] * e_dot - A[i] - k2[i] * s[i]
    # w = J^-1 a: R^T on the translation, T^-1 on the rotation.
    for i in range(3):
        w[i] = R[0, i] * a[0] + R[1, i] * a[1] + R[2, i] * a[2]
    cphi, sphi = math.cos(eta[3]), math.sin(eta[3])
    cth, sth = math.cos(eta[4]), math.sin(eta[4])
    w[3] = a[3] - sth * a[5]
    w[4] = cphi * a[4] + cth * sphi * a[5]
    w[5] = -sphi * a[4] + cth * cphi * a[5]
    coriolis_times_nu(p, nu, cnu)
    damping_times_nu(p, nu, dnu)
    restoring(p, eta, gvec)
    for i in range(6):
        acc = 0.0
        for j in range(6):
            acc += p[P_M + 6 * i + j] * w[j]
        tau[i] = acc + cnu[i] + dnu[i] + gvec[i] - tau_hat[i]
    # grad = M^-T (J^T s): J^T s = [R^T s1 ; T^T s2].
    for i in range(3):
        jts[i] = R[0, i] * s[0] + R[1, i] * s[1] + R[2, i] * s[2]
    tth = sth / cth
    jts[3] = s[3]
    jts[4] = sphi * tth * s[3] + cphi * s[4] + sphi / cth * s[5]
    jts[5] = cphi * tth * s[3] - sphi * s[4] + cphi / cth * s[5]
    for i in range(6):
        acc = 0.0
        for j in range(6):
            acc += p[P_MINV + 6 * j + i] * jts[j]
        grad[i] = acc


@njit(cache=True)
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


@njit(cache=True)
def adapt(schedule, grad, gamma, d_max, dt, tau_hat):
    """One explicit step of d(tau_hat)/dt = Gamma (J M^-1)^T s (ERRATA 3), projected onto |tau_hat_i| <= d_max_i
    (Assumption 2). Baseline (no schedule) keeps tau_hat = 0."""
    for i in range(6):
        if schedule == SCHEDULE_NONE:
            tau_hat[i] = 0.0
        else:
            value = tau_hat[i] + dt * gamma[i] * grad[i]
            tau_hat[i] = min(max(value, -d_max[i]), d_max[i])


@njit(cache=True)
def controller_step(p, k1, k2, schedule, gamma_const, table, table_xmax, d_max, eta, nu, ref, dt,
                    tau_hat, tau, s, grad, gamma, ws):
    """One control tick: tau from the law with the current estimate, then the estimate advanced by dt.

    tau_hat is updated in place; tau, s, grad, gamma are written (6,) each; ws: workspace (64,)."""
    control_law(p, k1, k2, eta, nu, ref, tau_hat, tau, s, grad, ws)
    adaptation_rates(schedule, grad, gamma_const, table, table_xmax, gamma)
    adapt(schedule, grad, gamma, d_max, dt, tau_hat)


@njit(cache=True)
def _diverged(x):
    for i in range(12):
        if not math.isfinite(x[i]):
            return True
    if abs(x[3]) > MAX_TILT or abs(x[4]) > MAX_TILT:
        return True
    for i in range(6, 12):
        if abs(x[i]) > MAX_SPEED:
            return True
    return False


@njit(cache=True)
def simulate_batch(plant, env, ctrl, gains, schedule, gamma_const, table, table_xmax, d_max, ref, dt,
                   substeps, x0, seeds, cost_q, cost_r, eta_log, nu_log, tau_log, tau_hat_log, s_log, gamma_log,
                   cost, steps_done):
    """Closed-loop runs of a batch of vehicles: law + adaptation at 1/dt, plant by RK4 at dt/substeps.

    plant (B, 92), env (B, 20): each run's true vehicle and environment; ctrl (92,): the controller's model;
    gains (B, 12) = [k1 | k2]; ref (N+1, 18): reference at t_k = k dt; x0 (12,); seeds (B,) for sensor noise.
    cost (B,) receives J = sum (s^T Q s + tau^T R tau) dt with Q = diag(cost_q), R = diag(cost_r) (Eq. 2.32);
    a diverging run stops early with DIVERGED_COST. steps_done (B,) receives the ticks completed.
    The *_log arrays are (B, N+1, 6) to record, or (B, 0, 6) to skip recording."""
    n_runs = gains.shape[0]
    n_steps = ref.shape[0] - 1
    record = eta_log.shape[1] > 0
    h = dt / substeps
    for b in range(n_runs):
        np.random.seed(seeds[b])
        x = x0.copy()
        ws_plant = np.zeros(128)
        ws_ctrl = np.zeros(64)
        eta_m = np.zeros(6)
        nu_m = np.zeros(6)
        tau_hat = np.zeros(6)
        tau = np.zeros(6)
        s = np.zeros(6)
        grad = np.zeros(6)
        gamma = np.zeros(6)
        k1 = gains[b, 0:6]
        k2 = gains[b, 6:12]
        noise = env[b, E_NOISE:E_NOISE + 4]
        total = 0.0
        done = n_steps
        for k in range(n_steps + 1):
            for i in range(6):
                sigma = noise[0] if i < 3 else noise[1]
                eta_m[i] = x[i] + (np.random.normal() * sigma if sigma > 0.0 else 0.0)
                sigma = noise[2] if i < 3 else noise[3]
                nu_m[i] = x[6 + i] + (np.random.normal() * sigma if sigma > 0.0 else 0.0)
            controller_step(ctrl, k1, k2, schedule, gamma_const, table, table_xmax, d_max, eta_m, nu_m, ref[k],
                            dt, tau_hat, tau, s, grad, gamma, ws_ctrl)
            if record:
                for i in range(6):
                    eta_log[b, k, i] = x[i]
                    nu_log[b, k, i] = x[6 + i]
                    tau_log[b, k, i] = tau[i]
                    tau_hat_log[b, k, i] = tau_hat[i]
                    s_log[b, k, i] = s[i]
                    gamma_log[b, k, i] = gamma[i]
            if k == n_steps:
                break
            for i in range(6):
                total += (cost_q[i] * s[i] * s[i] + cost_r[i] * tau[i] * tau[i]) * dt
            for j in range(substeps):
                rk4_step(plant[b], env[b], x, tau, k * dt + j * h, h, ws_plant)
            if _diverged(x):
                done = k + 1
                total = DIVERGED_COST
                break
        cost[b] = total
        steps_done[b] = done
