"""The compiled core: 6-DOF model, control law, adaptation and closed-loop simulation (Numba, cached).

Every path that moves the vehicle model or runs the law goes through these functions: the offline simulator and
the tuner (`simulate_batch`, a whole swarm in one call), the bridge's plant (`rk4_step`) and the runner
(`controller_step`). They work on flat float64 arrays and preallocated workspaces so the inner loop allocates
nothing. `rov_mav.dynamics` and `rov_mav.law` hold the readable matrix forms that the tests hold these to.

Conventions: eta = [x, y, z, phi, theta, psi] (NED, ZYX Euler), nu = [u, v, w, p, q, r] (body FRD).
Packed vehicle vector (see `rov_mav.vehicle.Vehicle.packed`): M (36), M^-1 (36), linear damping (6),
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


def printed_cost(ref: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """simulate_batch's (cost_weights, tau_ff, tau_max) for Eq. 2.32 as printed: Q = R = I, no saturation limit."""
    return np.array([np.ones(6), np.zeros(6), np.ones(6)]), np.zeros((ref.shape[0], 6)), np.full(6, np.inf)


# Floating-point licences for the compiled code: fused multiply-add and reassociation, but NaN and inf keep their
# meaning (the divergence check relies on them).
FAST = {"contract", "reassoc", "arcp", "nsz", "afn"}

# Every kernel function: cached to disk, numpy's error model (no Python-style division checks in the hot loop).
compiled = njit(cache=True, fastmath=FAST, error_model="numpy")


@compiled
def rotation(cphi, sphi, cth, sth, cpsi, spsi):
    """R(Theta), ZYX body-to-NED rotation (ERRATA 1, Fossen 2021 eq. 2.18), row-major 9-tuple."""
    return (cpsi * cth, -spsi * cphi + cpsi * sth * sphi, spsi * sphi + cpsi * cphi * sth,
            spsi * cth, cpsi * cphi + sphi * sth * spsi, -cpsi * sphi + sth * spsi * cphi,
            -sth, cth * sphi, cth * cphi)


@compiled
def euler_rates(cphi, sphi, cth, sth, p, q, r):
    """T(Theta) [p, q, r]: Euler-angle rates from body rates (Eq. 2.4), 3-tuple."""
    return (p + (sphi * q + cphi * r) * sth / cth, cphi * q - sphi * r, (sphi * q + cphi * r) / cth)


@compiled
def jacobian_dot_nu(R, cphi, sphi, cth, sth, dphi, dth, u, v, w, p, q, r):
    """A = J_dot(eta, eta_dot) nu (Eq. 2.15), 6-tuple.

    Translation: R_dot nu1 = R (omega x nu1). Rotation: T_dot nu2 with T_dot = phi_dot dT/dphi + theta_dot dT/dtheta."""
    cx = q * w - r * v
    cy = r * u - p * w
    cz = p * v - q * u
    tth = sth / cth
    sec2 = 1.0 / (cth * cth)
    return (R[0] * cx + R[1] * cy + R[2] * cz,
            R[3] * cx + R[4] * cy + R[5] * cz,
            R[6] * cx + R[7] * cy + R[8] * cz,
            dphi * (cphi * tth * q - sphi * tth * r) + dth * sec2 * (sphi * q + cphi * r),
            dphi * (-sphi * q - cphi * r),
            dphi * (cphi * q - sphi * r) / cth + dth * sth * sec2 * (sphi * q + cphi * r))


@compiled
def _mass_row(m, row, u, v, w, p, q, r):
    b = P_M + 6 * row
    return m[b] * u + m[b + 1] * v + m[b + 2] * w + m[b + 3] * p + m[b + 4] * q + m[b + 5] * r


@compiled
def coriolis_times_nu(m, u, v, w, p, q, r):
    """C(nu) nu with C built from M by Fossen's m2c (ERRATA 5), 6-tuple.

    C = [[0, -S(a)], [-S(a), -S(b)]], a = M11 nu1 + M12 nu2, b = M21 nu1 + M22 nu2, S(x)y = x cross y."""
    a0 = _mass_row(m, 0, u, v, w, p, q, r)
    a1 = _mass_row(m, 1, u, v, w, p, q, r)
    a2 = _mass_row(m, 2, u, v, w, p, q, r)
    b0 = _mass_row(m, 3, u, v, w, p, q, r)
    b1 = _mass_row(m, 4, u, v, w, p, q, r)
    b2 = _mass_row(m, 5, u, v, w, p, q, r)
    return (-(a1 * r - a2 * q), -(a2 * p - a0 * r), -(a0 * q - a1 * p),
            -(a1 * w - a2 * v) - (b1 * r - b2 * q),
            -(a2 * u - a0 * w) - (b2 * p - b0 * r),
            -(a0 * v - a1 * u) - (b0 * q - b1 * p))


@compiled
def damping_times_nu(m, u, v, w, p, q, r):
    """D(nu) nu = (D_l + D_nl(|nu|)) nu (Appendix I.3, positive magnitudes), 6-tuple."""
    lin, quad = P_DLIN, P_DQUAD
    return ((m[lin] + m[quad] * abs(u)) * u, (m[lin + 1] + m[quad + 1] * abs(v)) * v,
            (m[lin + 2] + m[quad + 2] * abs(w)) * w, (m[lin + 3] + m[quad + 3] * abs(p)) * p,
            (m[lin + 4] + m[quad + 4] * abs(q)) * q, (m[lin + 5] + m[quad + 5] * abs(r)) * r)


@compiled
def restoring(m, cphi, sphi, cth, sth):
    """g(eta), gravity and buoyancy (Appendix I.4), 6-tuple."""
    W, B = m[P_W], m[P_B]
    gx = m[P_RG] * W - m[P_RB] * B
    gy = m[P_RG + 1] * W - m[P_RB + 1] * B
    gz = m[P_RG + 2] * W - m[P_RB + 2] * B
    return ((W - B) * sth, -(W - B) * cth * sphi, -(W - B) * cth * cphi,
            -gy * cth * cphi + gz * cth * sphi, gz * sth + gx * cth * cphi, -gx * cth * sphi - gy * sth)


@compiled
def state_derivative(m, x, tau, current_ned, dx):
    """d/dt [eta; nu] for the plant (Eqs. 2.1, 2.7): M nu_dot = tau - C(nu) nu - D(nu_r) nu_r - g(eta).

    `tau` is the total body wrench (control + disturbance). A water current enters through the relative velocity
    nu_r = nu - [R^T v_c; 0] in the damping. x, dx: (12,)."""
    cphi, sphi = math.cos(x[3]), math.sin(x[3])
    cth, sth = math.cos(x[4]), math.sin(x[4])
    cpsi, spsi = math.cos(x[5]), math.sin(x[5])
    u, v, w, p, q, r = x[6], x[7], x[8], x[9], x[10], x[11]
    R = rotation(cphi, sphi, cth, sth, cpsi, spsi)
    dx[0] = R[0] * u + R[1] * v + R[2] * w
    dx[1] = R[3] * u + R[4] * v + R[5] * w
    dx[2] = R[6] * u + R[7] * v + R[8] * w
    dx[3], dx[4], dx[5] = euler_rates(cphi, sphi, cth, sth, p, q, r)
    cn, ce, cd = current_ned[0], current_ned[1], current_ned[2]
    ur = u - (R[0] * cn + R[3] * ce + R[6] * cd)
    vr = v - (R[1] * cn + R[4] * ce + R[7] * cd)
    wr = w - (R[2] * cn + R[5] * ce + R[8] * cd)
    c = coriolis_times_nu(m, u, v, w, p, q, r)
    d = damping_times_nu(m, ur, vr, wr, p, q, r)
    g = restoring(m, cphi, sphi, cth, sth)
    f0 = tau[0] - c[0] - d[0] - g[0]
    f1 = tau[1] - c[1] - d[1] - g[1]
    f2 = tau[2] - c[2] - d[2] - g[2]
    f3 = tau[3] - c[3] - d[3] - g[3]
    f4 = tau[4] - c[4] - d[4] - g[4]
    f5 = tau[5] - c[5] - d[5] - g[5]
    for i in range(6):
        b = P_MINV + 6 * i
        dx[6 + i] = m[b] * f0 + m[b + 1] * f1 + m[b + 2] * f2 + m[b + 3] * f3 + m[b + 4] * f4 + m[b + 5] * f5


@compiled
def disturbance(env, t, tau, out):
    """out = tau + tau_d(t), tau_d a constant plus a sinusoid per DOF (body frame, N and N m)."""
    period = env[E_PERIOD]
    phase = math.sin(2.0 * math.pi * t / period) if period > 0.0 else 0.0
    for i in range(6):
        out[i] = tau[i] + env[E_DIST + i] + env[E_AMP + i] * phase


@compiled
def rk4_step(m, env, x, tau, t, h, ws):
    """Advance the plant state x (12,) in place by h seconds with the control wrench tau held (classic RK4).

    The disturbance tau_d(t) is evaluated at t, t + h/2 and t + h. ws: workspace (80,)."""
    k1 = ws[0:12]
    k2 = ws[12:24]
    k3 = ws[24:36]
    k4 = ws[36:48]
    xs = ws[48:60]
    total = ws[60:66]
    current = env[E_CURRENT:E_CURRENT + 3]
    disturbance(env, t, tau, total)
    state_derivative(m, x, total, current, k1)
    disturbance(env, t + 0.5 * h, tau, total)
    for i in range(12):
        xs[i] = x[i] + 0.5 * h * k1[i]
    state_derivative(m, xs, total, current, k2)
    for i in range(12):
        xs[i] = x[i] + 0.5 * h * k2[i]
    state_derivative(m, xs, total, current, k3)
    disturbance(env, t + h, tau, total)
    for i in range(12):
        xs[i] = x[i] + h * k3[i]
    state_derivative(m, xs, total, current, k4)
    for i in range(12):
        x[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])


@compiled
def wrap_angle(a):
    """Wrap an angle to [-pi, pi)."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi


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
        tau[i] = _mass_row(m, i, wv0, wv1, wv2, wv3, wv4, wv5) + c[i] + d[i] + g[i] - tau_hat[i]
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


@compiled
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


@compiled
def _saturated(tau, tau_max):
    """True when a commanded |tau_i| exceeds tau_max_i: the thrusters cannot deliver it."""
    for i in range(6):
        if abs(tau[i]) > tau_max[i]:
            return True
    return False


@compiled
def _running_cost(weights, s, x, ref, tau, tau_ff):
    """s^T Q s + e^T Q_e e + (tau - tau_ff)^T R (tau - tau_ff) at one tick (Eq. 2.32 and its tracking form)."""
    total = 0.0
    for i in range(6):
        u = tau[i] - tau_ff[i]
        total += weights[0, i] * s[i] * s[i] + weights[2, i] * u * u
        if weights[1, i] != 0.0:
            e = x[i] - ref[i]
            if i >= 3:
                e = wrap_angle(e)
            total += weights[1, i] * e * e
    return total


@njit(cache=True, fastmath=FAST, error_model="numpy", nogil=True)
def simulate_batch(plant, env, ctrl, gains, schedule, gamma_const, table, table_xmax, d_max, ref, dt,
                   substeps, x0, seeds, cost_weights, tau_ff, tau_max, eta_log, nu_log, tau_log, tau_hat_log, s_log,
                   gamma_log, cost, steps_done):
    """Closed-loop runs of a batch of vehicles: law + adaptation at 1/dt, plant by RK4 at dt/substeps.

    plant (B, 92), env (B, 20): each run's true vehicle and environment; ctrl (92,): the controller's model;
    gains (B, 12) = [k1 | k2]; ref (N+1, 18): reference at t_k = k dt; x0 (12,); seeds (B,) for sensor noise.
    cost (B,) receives Eq. 2.32 extended, J = sum (s^T Q s + e^T Q_e e + u^T R u) dt with u = tau - tau_ff[k],
    e the true tracking error and cost_weights (3, 6) = diagonals of [Q; Q_e; R] (the printed Eq. 2.32:
    Q = R = I, Q_e = 0, tau_ff = 0). A run stops early with DIVERGED_COST when it diverges or when a commanded
    |tau_i| exceeds tau_max (6,) (thruster saturation). steps_done (B,) receives the index of the last tick
    logged (N for a run that completed; a run that ends early stops at the last state before it failed).
    The *_log arrays are (B, N+1, 6) to record, or (B, 0, 6) to skip recording.
    Releases the GIL: callers may run disjoint slices of a batch in parallel threads."""
    n_runs = gains.shape[0]
    n_steps = ref.shape[0] - 1
    record = eta_log.shape[1] > 0
    h = dt / substeps
    for b in range(n_runs):
        np.random.seed(seeds[b])
        x = x0.copy()
        ws_plant = np.zeros(80)
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
                            dt, tau_hat, tau, s, grad, gamma)
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
            if _saturated(tau, tau_max):
                done = k
                total = DIVERGED_COST
                break
            total += _running_cost(cost_weights, s, x, ref[k], tau, tau_ff[k]) * dt
            for j in range(substeps):
                rk4_step(plant[b], env[b], x, tau, k * dt + j * h, h, ws_plant)
            if _diverged(x):
                done = k
                total = DIVERGED_COST
                break
        cost[b] = total
        steps_done[b] = done
