"""Sliding mode control per DOF with a boundary layer, compiled.

The classic first-order design with a boundary layer (Slotine and Li, Applied Nonlinear Control, 1991, Ch. 7:
sliding surfaces, 7.1-7.2; the boundary layer sat(s/phi), 7.3; Fossen, Handbook of Marine Craft Hydrodynamics and
Motion Control, 2nd ed. 2021, the sliding-mode chapter, for marine craft), in the decoupled per-DOF form that
benchmarks of the BlueROV2 compare against (the vehicle model itself is von Benzon et al.'s benchmark, J. Mar. Sci.
Eng. 10(12) 1898, 2022; their paper's own controller equations were not at hand, so this follows Slotine and Li).
Per DOF i, with e = eta - eta_d (angles wrapped):

    s_eta = e_dot + lambda e,       s = J^-1 s_eta = nu - nu_r,   nu_r = J^-1 (eta_dot_d - lambda e)
    nu_r_dot = J^-1 (eta_ddot_d - lambda e_dot - J_dot nu)
    tau_i = M_ii nu_r_dot_i + D_i(nu_i) nu_i + g_i(eta) - K_i sat(s_i / phi_i)

a nominal decoupled model (the diagonal of M, the diagonal damping, the restoring wrench; no Coriolis or
off-diagonal coupling: K must dominate what is left out) and a switching gain K smoothed inside a boundary layer
of thickness phi (sat(x) = x for |x| <= 1, sign(x) beyond). Parameter vector: [lambda (6) | K (6) | phi (6)]; no
state. s (logged) is the body-frame sliding variable; tau_hat is K sat(s/phi), the switching wrench read as the
disturbance it holds off.
"""

from __future__ import annotations

from rov_mav.model.kernel import (
    P_M,
    body_from_earth,
    compiled,
    inlined,
    damping_times_nu,
    restoring,
    state_kinematics,
    tracking_error,
)

PARAMETERS = (("lam", 6), ("k", 6), ("phi", 6))
TUNED = ("lam", "k", "phi")
BOUNDS = {"lam": (0.1, 5.0),
          "k": ([1.0, 1.0, 1.0, 0.1, 0.1, 0.1], [150.0, 150.0, 150.0, 15.0, 15.0, 15.0]),
          "phi": (0.01, 1.0)}
STATE_SIZE = 0


@inlined
def saturation(x):
    return min(max(x, -1.0), 1.0)


@inlined
def step(m, params, eta, trig, nu, ref, tau, tau_hat, s):
    """One tick: writes tau, tau_hat, s (6,) each."""
    lam, k, phi = params[0:6], params[6:12], params[12:18]
    cphi, sphi, cth, sth, R, eta_dot, A = state_kinematics(trig, nu)
    u, v, w, p, q, r = nu[0], nu[1], nu[2], nu[3], nu[4], nu[5]
    acc = tau_hat   # scratch: the reference acceleration in the eta frame, consumed before tau_hat is written
    for i in range(6):
        e, e_dot = tracking_error(eta, eta_dot, ref, i)
        s[i] = e_dot + lam[i] * e
        acc[i] = ref[12 + i] - lam[i] * e_dot - A[i]
    acc_body = body_from_earth(cphi, sphi, cth, sth, R, acc)
    s_body = body_from_earth(cphi, sphi, cth, sth, R, s)
    d = damping_times_nu(m, u, v, w, p, q, r)
    g = restoring(m, cphi, sphi, cth, sth)
    for i in range(6):
        switching = k[i] * saturation(s_body[i] / phi[i])
        tau[i] = m[P_M + 7 * i] * acc_body[i] + d[i] + g[i] - switching
        tau_hat[i] = switching
        s[i] = s_body[i]
