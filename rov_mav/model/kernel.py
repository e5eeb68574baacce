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
# period and delay (2, s; 0 = the controller measures every tick, without delay).
E_DIST = 0
E_AMP = 6
E_PERIOD = 12
E_CURRENT = 13
E_NOISE = 16
E_SAMPLE_PERIOD = 20
E_SAMPLE_DELAY = 21
E_SIZE = 22

# Floating-point licences for the compiled code: fused multiply-add and reassociation, but NaN and inf keep their
# meaning (the divergence check relies on them).
FAST = {"contract", "reassoc", "arcp", "nsz", "afn"}

# Every kernel function: cached to disk, numpy's error model (no Python-style division checks in the hot loop), and
# compiled without Numba's reference counting (`_nrt=False`): kernel functions never allocate, and each array view
# or array argument would otherwise cost two calls that update a counter atomically, most of a law's time.
compiled = njit(cache=True, fastmath=FAST, error_model="numpy", _nrt=False)
# The same, inlined into its caller at Numba's IR level: for the glue between the laws and the loop and for the RK4
# stages, whose calls pass many arrays (seven arguments each). The arithmetic leaves stay `compiled` (LLVM inlines the
# small ones): inlining them at Numba's level too would triple the cold compile for no measured gain.
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


@compiled
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


@compiled
def disturbance(env, t, tau, out):
    """out = tau + tau_d(t), tau_d a constant plus a sinusoid per DOF (body frame, N and N m)."""
    period = env[E_PERIOD]
    phase = math.sin(2.0 * math.pi * t / period) if period > 0.0 else 0.0
    for i in range(6):
        out[i] = tau[i] + env[E_DIST + i] + env[E_AMP + i] * phase


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


@compiled
def rk4_step(m, env, x, tau, t, h, ws):
    """Advance the plant state x (12,) in place by h seconds with the control wrench tau held (classic RK4).

    The disturbance tau_d(t) is evaluated at t, t + h/2 and t + h. The attitude's sines and cosines are turned by
    each stage's small angle increment (`stage_trig`) and on to the next step's attitude (`carried_trig`), computed
    afresh every TRIG_REFRESH steps or when x's attitude is not the one this left. ws: workspace (80,), zeroed before
    a first step."""
    k1 = ws[0:12]
    k2 = ws[12:24]
    k3 = ws[24:36]
    k4 = ws[36:48]
    xs = ws[48:60]
    total = ws[60:66]
    current = env[E_CURRENT:E_CURRENT + 3]
    trig = carried_trig(x, ws)
    disturbance(env, t, tau, total)
    derivative_at(m, x, trig, total, current, k1)
    disturbance(env, t + 0.5 * h, tau, total)
    for i in range(12):
        xs[i] = x[i] + 0.5 * h * k1[i]
    derivative_at(m, xs, stage_trig(trig, xs, 0.5 * h, k1), total, current, k2)
    for i in range(12):
        xs[i] = x[i] + 0.5 * h * k2[i]
    derivative_at(m, xs, stage_trig(trig, xs, 0.5 * h, k2), total, current, k3)
    disturbance(env, t + h, tau, total)
    for i in range(12):
        xs[i] = x[i] + h * k3[i]
    derivative_at(m, xs, stage_trig(trig, xs, h, k3), total, current, k4)
    for i in range(12):
        x[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
    for i in range(3):
        xs[3 + i] = x[3 + i] - ws[66 + i]   # the attitude's increment (exact for close values, Sterbenz)
        ws[66 + i] = x[3 + i]
    ws[69], ws[70], ws[71], ws[72], ws[73], ws[74] = stage_trig(trig, x, 1.0, xs)


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
