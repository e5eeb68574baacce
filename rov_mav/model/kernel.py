"""The compiled 6-DOF model (Numba, cached): kinematics, Coriolis, damping, restoring, disturbance, RK4.

Every path that moves the vehicle model goes through these functions: the offline closed loop
(`rov_mav.offline.loop_kernel`), the bridge's plant (`rk4_step`) and, through the law, the runner. They work on flat
float64 arrays and preallocated workspaces so the inner loop allocates nothing. `rov_mav.model.dynamics` holds the
readable matrix forms that the tests hold these to.

Conventions: eta = [x, y, z, phi, theta, psi] (NED, ZYX Euler), nu = [u, v, w, p, q, r] (body FRD).
Packed vehicle vector (see `rov_mav.model.vehicle.Vehicle.packed`): M (36), M^-1 (36), linear damping (6),
quadratic damping (6), W, B, r_g (3), r_b (3).
"""

from __future__ import annotations

import math

from numba import njit

from rov_mav.model import kernel_cache

kernel_cache.install()   # before any kernel is decorated: a kernel's cache is stale after an edit to any kernel source

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
# NED current (3), sensor noise std for position, attitude, linear velocity, angular rate (4), telemetry sample
# period and delay (2, s; 0 = the controller measures every tick, without delay), whether the controller
# predicts its late measurement forward (1) or acts on it as it is (0), and the thrusters' faults as the offline loop
# meets them: from E_FAULT_AT s (inf: never) the wrench the thrusters give is F tau + push, F (6 x 6, row-major) and
# push (6) from `rov_mav.model.vehicle_faults.wrench_map` (the bridge applies thruster faults to its thrusters
# instead, and packs none).
E_DIST = 0
E_AMP = 6
E_PERIOD = 12
E_CURRENT = 13
E_NOISE = 16
E_SAMPLE_PERIOD = 20
E_SAMPLE_DELAY = 21
E_PREDICT = 22
E_FAULT_AT = 23
E_FAULT_MAP = 24
E_FAULT_PUSH = 60
E_SIZE = 66

# Floating-point licences for the compiled code: fused multiply-add and reassociation, but NaN and inf keep their
# meaning (the divergence check relies on them).
FAST = {"contract", "reassoc", "arcp", "nsz", "afn"}

# Every kernel function: cached to disk, numpy's error model (no Python-style division checks in the hot loop), and
# compiled without Numba's reference counting (`_nrt=False`): kernel functions never allocate, and each array view
# or array argument would otherwise cost two calls that update a counter atomically, most of a law's time.
compiled = njit(cache=True, fastmath=FAST, error_model="numpy", _nrt=False)
# The same, inlined into its caller at Numba's IR level: for the glue between the laws and the loop and for the RK4
# stages, whose calls pass many arrays (seven arguments each). The arithmetic leaves stay `compiled` (LLVM inlines the
# small ones): inlining them all at Numba's level too would lengthen the cold compile by a third for little. The
# exception is `coriolis_times_nu`, too large for LLVM to inline and called in every RK4 stage and law: inlined, a
# particle-step takes about 10 % less (the cold compile 5 % more).
inlined = njit(cache=True, fastmath=FAST, error_model="numpy", inline="always", _nrt=False)
# A function that allocates (reference counting on).
allocating = njit(cache=True, fastmath=FAST, error_model="numpy")
# A whole closed loop over kernel functions: called (not inlined) once per run, releasing the GIL.
compiled_loop = njit(cache=True, fastmath=FAST, error_model="numpy", nogil=True, _nrt=False)


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
def mass_row(m, row, u, v, w, p, q, r):
    b = P_M + 6 * row
    return m[b] * u + m[b + 1] * v + m[b + 2] * w + m[b + 3] * p + m[b + 4] * q + m[b + 5] * r


@inlined
def coriolis_times_nu(m, u, v, w, p, q, r):
    """C(nu) nu with C built from M by Fossen's m2c (ERRATA 5), 6-tuple.

    C = [[0, -S(a)], [-S(a), -S(b)]], a = M11 nu1 + M12 nu2, b = M21 nu1 + M22 nu2, S(x)y = x cross y."""
    a0 = mass_row(m, 0, u, v, w, p, q, r)
    a1 = mass_row(m, 1, u, v, w, p, q, r)
    a2 = mass_row(m, 2, u, v, w, p, q, r)
    b0 = mass_row(m, 3, u, v, w, p, q, r)
    b1 = mass_row(m, 4, u, v, w, p, q, r)
    b2 = mass_row(m, 5, u, v, w, p, q, r)
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
    derivative_at(m, x, attitude_trig(x), tau, current_ned, dx)


@inlined
def attitude_trig(x):
    """(cos phi, sin phi, cos theta, sin theta, cos psi, sin psi) of the state x."""
    return math.cos(x[3]), math.sin(x[3]), math.cos(x[4]), math.sin(x[4]), math.cos(x[5]), math.sin(x[5])


# rad: a turn up to this is rotated by series (cos d to d^8 and sin d to d^9: truncated below 1e-19).
SMALL_TURN = 0.05


@inlined
def turned(c, s, angle, d):
    """(cos, sin) of angle = a + d from c = cos a, s = sin a by the angle-addition formulas, cos d and sin d from
    their Taylor series when |d| <= SMALL_TURN (a library call otherwise): what an RK4 stage needs a few ns for."""
    if abs(d) > SMALL_TURN:
        return math.cos(angle), math.sin(angle)
    d2 = d * d
    cd = 1.0 - d2 / 2.0 * (1.0 - d2 / 12.0 * (1.0 - d2 / 30.0 * (1.0 - d2 / 56.0)))
    sd = d * (1.0 - d2 / 6.0 * (1.0 - d2 / 20.0 * (1.0 - d2 / 42.0 * (1.0 - d2 / 72.0))))
    return c * cd - s * sd, s * cd + c * sd


@inlined
def stage_trig(trig, xs, step, k):
    """attitude_trig(xs) for the RK4 stage xs = x + step k, from trig = attitude_trig(x)."""
    cphi, sphi = turned(trig[0], trig[1], xs[3], step * k[3])
    cth, sth = turned(trig[2], trig[3], xs[4], step * k[4])
    cpsi, spsi = turned(trig[4], trig[5], xs[5], step * k[5])
    return cphi, sphi, cth, sth, cpsi, spsi


@inlined
def derivative_at(m, x, trig, tau, current_ned, dx):
    """state_derivative with the attitude's trig = attitude_trig(x) given."""
    cphi, sphi, cth, sth, cpsi, spsi = trig
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


# Steps an attitude's sines and cosines are carried from step to step before they are computed afresh: bounds the
# rounding they gather (about one unit in the last place a step).
TRIG_REFRESH = 64


@inlined
def carried_trig(x, ws):
    """attitude_trig(x), carried over in ws[66:76] = [attitude (3), its trig (6), steps left] when x's attitude is
    the one rk4_step left there, else computed afresh (and the attitude noted)."""
    if ws[75] > 0.0 and x[3] == ws[66] and x[4] == ws[67] and x[5] == ws[68]:
        ws[75] -= 1.0
        return ws[69], ws[70], ws[71], ws[72], ws[73], ws[74]
    ws[66], ws[67], ws[68], ws[75] = x[3], x[4], x[5], TRIG_REFRESH
    return attitude_trig(x)


@inlined
def disturbed(env, t, tau):
    """tau + tau_d(t) as a 6-tuple, tau_d a constant plus a sinusoid per DOF (body frame, N and N m)."""
    period = env[E_PERIOD]
    phase = math.sin(2.0 * math.pi * t / period) if period > 0.0 else 0.0
    return (tau[0] + env[E_DIST] + env[E_AMP] * phase, tau[1] + env[E_DIST + 1] + env[E_AMP + 1] * phase,
            tau[2] + env[E_DIST + 2] + env[E_AMP + 2] * phase, tau[3] + env[E_DIST + 3] + env[E_AMP + 3] * phase,
            tau[4] + env[E_DIST + 4] + env[E_AMP + 4] * phase, tau[5] + env[E_DIST + 5] + env[E_AMP + 5] * phase)


@inlined
def rk4_stages(m, x, trig, w_start, w_mid, w_end, current, h, ws):
    """One classic RK4 step of h seconds of the state x (12,), in place, for a wrench that is w_start at the step's
    start, w_mid at its middle and w_end at its end (the RK4 of a time-varying input); trig = attitude_trig(x).
    The stages' sines and cosines are turned by their small angle increments (`stage_trig`). Returns
    attitude_trig of the new x, turned the same way. ws: scratch (60,)."""
    k1 = ws[0:12]
    k2 = ws[12:24]
    k3 = ws[24:36]
    k4 = ws[36:48]
    xs = ws[48:60]
    derivative_at(m, x, trig, w_start, current, k1)
    for i in range(12):
        xs[i] = x[i] + 0.5 * h * k1[i]
    derivative_at(m, xs, stage_trig(trig, xs, 0.5 * h, k1), w_mid, current, k2)
    for i in range(12):
        xs[i] = x[i] + 0.5 * h * k2[i]
    derivative_at(m, xs, stage_trig(trig, xs, 0.5 * h, k2), w_mid, current, k3)
    for i in range(12):
        xs[i] = x[i] + h * k3[i]
    derivative_at(m, xs, stage_trig(trig, xs, h, k3), w_end, current, k4)
    for i in range(12):
        before = x[i]
        x[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
        xs[i] = x[i] - before          # the step's increment (exact for close values, Sterbenz)
    return stage_trig(trig, x, 1.0, xs)


@compiled
def rk4_step(m, env, x, tau, t, h, ws):
    """Advance the plant state x (12,) in place by h seconds with the control wrench tau held (classic RK4).

    The disturbance tau_d(t) is evaluated at t, t + h/2 and t + h. The attitude's sines and cosines are turned by
    each stage's small angle increment (`stage_trig`) and on to the next step's attitude (`carried_trig`), computed
    afresh every TRIG_REFRESH steps or when x's attitude is not the one this left. ws: workspace (80,), zeroed before
    a first step."""
    trig = carried_trig(x, ws)
    current = env[E_CURRENT:E_CURRENT + 3]
    trig = rk4_stages(m, x, trig, disturbed(env, t, tau), disturbed(env, t + 0.5 * h, tau),
                      disturbed(env, t + h, tau), current, h, ws)
    ws[66], ws[67], ws[68] = x[3], x[4], x[5]
    ws[69], ws[70], ws[71], ws[72], ws[73], ws[74] = trig


# s: the longest RK4 step of a prediction (the model's fastest motions, roll and pitch, take seconds).
PREDICT_STEP = 0.1
# s: the time constant of the prediction's disturbance estimate (`observe_disturbance`): long enough to average the
# velocity noise of many samples, short against a 6 s wave.
OBSERVER_TIME = 1.0
STILL_WATER = (0.0, 0.0, 0.0)


@inlined
def mean_wrench(ring, newest, slot, late, early, d):
    """The mean of the commanded wrench between `late` and `early` s (late < early) before a prediction's instant,
    plus d (6,): ring (R, 6) circular, ring[newest] the wrench over the last `slot` s, each entry held for its slot
    (the oldest entry holds before it). 6-tuple."""
    size = ring.shape[0]
    w0 = w1 = w2 = w3 = w4 = w5 = 0.0
    first = int(late / slot)
    j = first
    while True:
        lo = max(late, j * slot)
        hi = early if j >= size - 1 else min(early, (j + 1) * slot)
        if hi > lo:
            span = hi - lo
            row = ring[(newest - j) % size]
            w0 += row[0] * span
            w1 += row[1] * span
            w2 += row[2] * span
            w3 += row[3] * span
            w4 += row[4] * span
            w5 += row[5] * span
        if hi >= early:
            break
        j += 1
    k = 1.0 / (early - late)
    return (w0 * k + d[0], w1 * k + d[1], w2 * k + d[2], w3 * k + d[3], w4 * k + d[4], w5 * k + d[5])


@inlined
def predict(m, x, trig, ring, newest, slot, horizon, d_hat, out, ws):
    """The state `horizon` s after the measured x (12,) (trig = attitude_trig(x)), through the controller's model m
    in still water, under the wrenches commanded since plus the estimated disturbance d_hat (6,, body frame): ring
    (R, 6) is circular, ring[newest] the wrench that acts over the last `slot` s before the prediction's instant,
    ring[newest - 1] the slot before, and so on. RK4 steps of at most PREDICT_STEP under the mean wrench of their span
    (the velocity change each step is then exact in the wrench, however often the commands changed). Writes out
    (12,); returns attitude_trig(out). Horizon 0: out = x. ws: scratch (60,)."""
    for i in range(12):
        out[i] = x[i]
    if horizon <= 0.0:
        return trig
    n = int(math.ceil(horizon / PREDICT_STEP - 1e-9))   # a horizon a rounding above a step is one step
    h = horizon / n
    for j in range(n):
        w = mean_wrench(ring, newest, slot, max(horizon - (j + 1) * h, 0.0), horizon - j * h, d_hat)
        trig = rk4_stages(m, out, trig, w, w, w, STILL_WATER, h, ws)
    return trig


@inlined
def observe_disturbance(m, x_prev, trig_prev, ring, newest, slot, interval, x_new, d_hat, ws):
    """The disturbance the prediction adds, learnt from each new measurement: the model carries the previous
    measurement x_prev over the `interval` s to the new one's time under the wrenches commanded then (ring[newest]
    the last of them) and d_hat; what the new measured velocity x_new[6:12] differs by is a wrench
    M (nu_new - nu_model) / interval, of which interval / OBSERVER_TIME (at most half) is added to d_hat (in place): a
    first-order filter of time constant OBSERVER_TIME, whatever the sample rate. Without it, a steady
    disturbance would bias every prediction by M^-1 tau_d times the horizon. ws: scratch (72,)."""
    if interval <= 0.0:
        return
    model = ws[60:72]
    predict(m, x_prev, trig_prev, ring, newest, slot, interval, d_hat, model, ws[0:60])
    k = min(interval / OBSERVER_TIME, 0.5) / interval
    for i in range(6):
        d_hat[i] += k * mass_row(m, i, x_new[6] - model[6], x_new[7] - model[7], x_new[8] - model[8],
                                 x_new[9] - model[9], x_new[10] - model[10], x_new[11] - model[11])


@compiled
def wrap_angle(a):
    """Wrap an angle to [-pi, pi): an angle already inside is returned as it is (the floating-point remainder, a
    library call, only for the rest)."""
    if -math.pi <= a < math.pi:
        return a
    return (a + math.pi) % (2.0 * math.pi) - math.pi


@inlined
def body_from_earth(cphi, sphi, cth, sth, R, a):
    """J(eta)^-1 a for a (6,) in the eta frame: R^T on the translation, T^-1 on the rotation (Eq. 2.4), 6-tuple."""
    return (R[0] * a[0] + R[3] * a[1] + R[6] * a[2],
            R[1] * a[0] + R[4] * a[1] + R[7] * a[2],
            R[2] * a[0] + R[5] * a[1] + R[8] * a[2],
            a[3] - sth * a[5],
            cphi * a[4] + cth * sphi * a[5],
            -sphi * a[4] + cth * cphi * a[5])


@inlined
def trig_near(eta, x, ws):
    """attitude_trig(eta) for an attitude near the plant state x's: turned from the trig rk4_step carried for x in
    its workspace ws by eta - x (the sensor noise and the telemetry delay, small), when that trig is there and not
    due for its refresh; computed afresh otherwise."""
    if ws[75] > 0.0 and x[3] == ws[66] and x[4] == ws[67] and x[5] == ws[68]:
        if eta[3] == x[3] and eta[4] == x[4] and eta[5] == x[5]:
            return ws[69], ws[70], ws[71], ws[72], ws[73], ws[74]
        cphi, sphi = turned(ws[69], ws[70], eta[3], eta[3] - x[3])
        cth, sth = turned(ws[71], ws[72], eta[4], eta[4] - x[4])
        cpsi, spsi = turned(ws[73], ws[74], eta[5], eta[5] - x[5])
        return cphi, sphi, cth, sth, cpsi, spsi
    return attitude_trig(eta)


@inlined
def state_kinematics(trig, nu):
    """What every law starts from, given trig = attitude_trig(eta): (cphi, sphi, cth, sth, R, eta_dot, A) with R the
    body-to-NED rotation (9-tuple, row-major), eta_dot = J(eta) nu (Eq. 2.4) and A = J_dot(eta) nu, both 6-tuples."""
    cphi, sphi, cth, sth, cpsi, spsi = trig
    R = rotation(cphi, sphi, cth, sth, cpsi, spsi)
    u, v, w, p, q, r = nu[0], nu[1], nu[2], nu[3], nu[4], nu[5]
    dphi, dth, dpsi = euler_rates(cphi, sphi, cth, sth, p, q, r)
    eta_dot = (R[0] * u + R[1] * v + R[2] * w, R[3] * u + R[4] * v + R[5] * w,
               R[6] * u + R[7] * v + R[8] * w, dphi, dth, dpsi)
    A = jacobian_dot_nu(R, cphi, sphi, cth, sth, dphi, dth, u, v, w, p, q, r)
    return cphi, sphi, cth, sth, R, eta_dot, A


@inlined
def tracking_error(eta, eta_dot, ref, i):
    """(e_i, e_dot_i): the error of DOF i against ref = [eta_d, eta_dot_d, eta_ddot_d], angles wrapped (Eq. 2.13)."""
    e = eta[i] - ref[i]
    if i >= 3:
        e = wrap_angle(e)
    return e, eta_dot[i] - ref[6 + i]
