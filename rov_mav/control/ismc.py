"""Integral sliding mode control with the model's feed-forward, compiled.

The velocity-level law of the ROS 2 package auv_controllers (Robotic-Decision-Making-Lab, velocity_controllers/
src/integral_sliding_mode_controller.cpp, IntegralSlidingModeController::update_and_write_commands; designed in
E. Palmer, C. Holm, G. Hollinger, "Angler: An Autonomy Framework for Intervention Tasks with Lightweight Underwater
Vehicle Manipulator Systems", ICRA 2024), fed by a kinematic position loop (the velocity reference such a chained
controller receives). With e = eta - eta_d (angles wrapped) and the body-frame velocity error nu_e = nu_d - nu:

    nu_d     = J^-1 (eta_dot_d - K_pos e)                       position loop, reference-velocity feed-forward
    nu_d_dot = J^-1 (eta_ddot_d - K_pos e_dot - J_dot nu)        reference acceleration (auv_controllers: 0)
    tau_0    = M (nu_d_dot + K_p nu_e) + C(nu) nu + D(nu) nu + g(eta)
    s        = nu_e - nu_e(0) + K_p integral(nu_e dt)            s(0) = 0, the integral sliding surface
    tau      = tau_0 + K tanh(s / phi)

On the model, s_dot = -M^-1 (K tanh(s/phi) + tau_d): the switching term rejects the matched disturbance tau_d and
the integral removes the steady error. auv_controllers writes the surface's initial term as K_p nu_e(0); we use
nu_e(0) so that s(0) = 0 (Utkin's integral sliding mode). Parameter vector: [K_pos (6) | K_p (6) | K (6) | phi (6)];
state: integral of nu_e (6), nu_e(0) (6), started flag (1), 1/phi (6, set on the first tick: a multiplication
per DOF and tick instead of a division). tau_hat (logged) is -K tanh(s/phi), the disturbance the switching term
cancels.
"""

from __future__ import annotations

import math

from rov_mav.model.kernel import (
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

PARAMETERS = (("k_pos", 6), ("kp", 6), ("k", 6), ("phi", 6))
TUNED = ("k_pos", "kp", "k", "phi")
BOUNDS = {"k_pos": (0.1, 5.0),
          "kp": (0.1, 10.0),
          "k": ([0.5, 0.5, 0.5, 0.05, 0.05, 0.05], [100.0, 100.0, 100.0, 10.0, 10.0, 10.0]),
          "phi": (0.01, 1.0)}
STATE_SIZE = 19


@compiled
def tanh(x):
    """tanh x as (1 - e^-2|x|) / (1 + e^-2|x|) with x's sign: one exp, half the time of the library's tanh, within
    2.3e-16 of it (absolute)."""
    t = math.exp(-2.0 * abs(x))
    return math.copysign((1.0 - t) / (1.0 + t), x)


@inlined
def step(m, params, eta, trig, nu, ref, dt, state, tau, tau_hat, s):
    """One tick: writes tau, tau_hat, s (6,) each; updates state."""
    k_pos, kp, k, phi = params[0:6], params[6:12], params[12:18], params[18:24]
    integral, initial, inverse_phi = state[0:6], state[6:12], state[13:19]
    started = state[12] != 0.0
    if not started:
        for i in range(6):
            inverse_phi[i] = 1.0 / phi[i]
    cphi, sphi, cth, sth, R, eta_dot, A = state_kinematics(trig, nu)
    u, v, w, p, q, r = nu[0], nu[1], nu[2], nu[3], nu[4], nu[5]
    target, accel = s, tau_hat   # scratch in the eta frame, consumed before s and tau_hat are written
    for i in range(6):
        e, e_dot = tracking_error(eta, eta_dot, ref, i)
        target[i] = ref[6 + i] - k_pos[i] * e
        accel[i] = ref[12 + i] - k_pos[i] * e_dot - A[i]
    nu_d = body_from_earth(cphi, sphi, cth, sth, R, target)
    nu_d_dot = body_from_earth(cphi, sphi, cth, sth, R, accel)
    a0 = nu_d_dot[0] + kp[0] * (nu_d[0] - u)
    a1 = nu_d_dot[1] + kp[1] * (nu_d[1] - v)
    a2 = nu_d_dot[2] + kp[2] * (nu_d[2] - w)
    a3 = nu_d_dot[3] + kp[3] * (nu_d[3] - p)
    a4 = nu_d_dot[4] + kp[4] * (nu_d[4] - q)
    a5 = nu_d_dot[5] + kp[5] * (nu_d[5] - r)
    a = (a0, a1, a2, a3, a4, a5)
    c = coriolis_times_nu(m, u, v, w, p, q, r)
    d = damping_times_nu(m, u, v, w, p, q, r)
    g = restoring(m, cphi, sphi, cth, sth)
    for i in range(6):   # no calls in this loop: it unrolls, and the tuples' indices are constants
        error = nu_d[i] - nu[i]
        if started:
            integral[i] += error * dt
        else:
            initial[i] = error
        s[i] = error - initial[i] + kp[i] * integral[i]
        tau[i] = mass_row(m, i, a[0], a[1], a[2], a[3], a[4], a[5]) + c[i] + d[i] + g[i]
    for i in range(6):
        tau_hat[i] = -k[i] * tanh(s[i] * inverse_phi[i])
        tau[i] -= tau_hat[i]
    state[12] = 1.0
