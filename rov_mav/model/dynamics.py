"""The 6-DOF model in readable matrix form (Eqs. 2.1-2.7, Appendix I), batched over a leading axis.

This is the textbook statement of what `rov_mav.model.kernel` computes element by element; the tests hold the compiled
kernel to it. Shapes: eta, nu (..., 6); matrices (..., 6, 6).
"""

from __future__ import annotations

import math

import numpy as np

from rov_mav.model.vehicle import Vehicle


def skew(a: np.ndarray) -> np.ndarray:
    """S(a) with S(a) b = a x b; (..., 3) -> (..., 3, 3)."""
    a = np.asarray(a, dtype=float)
    z = np.zeros(a.shape[:-1])
    x, y, w = a[..., 0], a[..., 1], a[..., 2]
    return np.stack([np.stack([z, -w, y], -1), np.stack([w, z, -x], -1), np.stack([-y, x, z], -1)], -2)


def rotation(eta: np.ndarray) -> np.ndarray:
    """R(Theta) = Rz(psi) Ry(theta) Rx(phi), body to NED (ERRATA 1); (..., 6) -> (..., 3, 3). One pose (6,) is
    multiplied out in closed form (`attitude_rotation`): the runner and the built-in vehicle ask for one every tick."""
    eta = np.asarray(eta, dtype=float)
    if eta.ndim == 1:
        return attitude_rotation(float(eta[3]), float(eta[4]), float(eta[5]))
    phi, theta, psi = eta[..., 3], eta[..., 4], eta[..., 5]
    one, zero = np.ones_like(phi), np.zeros_like(phi)
    rx = np.stack([np.stack([one, zero, zero], -1),
                   np.stack([zero, np.cos(phi), -np.sin(phi)], -1),
                   np.stack([zero, np.sin(phi), np.cos(phi)], -1)], -2)
    ry = np.stack([np.stack([np.cos(theta), zero, np.sin(theta)], -1),
                   np.stack([zero, one, zero], -1),
                   np.stack([-np.sin(theta), zero, np.cos(theta)], -1)], -2)
    rz = np.stack([np.stack([np.cos(psi), -np.sin(psi), zero], -1),
                   np.stack([np.sin(psi), np.cos(psi), zero], -1),
                   np.stack([zero, zero, one], -1)], -2)
    return rz @ ry @ rx


def attitude_rotation(phi: float, theta: float, psi: float) -> np.ndarray:
    """Rz(psi) Ry(theta) Rx(phi) for one attitude, multiplied out."""
    cf, sf, ct, st, cp, sp = math.cos(phi), math.sin(phi), math.cos(theta), math.sin(theta), math.cos(psi), \
        math.sin(psi)
    return np.array([[cp * ct, cp * st * sf - sp * cf, cp * st * cf + sp * sf],
                     [sp * ct, sp * st * sf + cp * cf, sp * st * cf - cp * sf],
                     [-st, ct * sf, ct * cf]])


def euler_rate_matrix(eta: np.ndarray) -> np.ndarray:
    """T(Theta) of Eq. 2.4 (J_r); (..., 6) -> (..., 3, 3)."""
    eta = np.asarray(eta, dtype=float)
    phi, theta = eta[..., 3], eta[..., 4]
    sp, cp, ct, tt = np.sin(phi), np.cos(phi), np.cos(theta), np.tan(theta)
    one, zero = np.ones_like(phi), np.zeros_like(phi)
    return np.stack([np.stack([one, sp * tt, cp * tt], -1),
                     np.stack([zero, cp, -sp], -1),
                     np.stack([zero, sp / ct, cp / ct], -1)], -2)


def jacobian(eta: np.ndarray) -> np.ndarray:
    """J(eta) = diag(R, T) (Eq. 2.2); (..., 6) -> (..., 6, 6)."""
    eta = np.asarray(eta, dtype=float)
    J = np.zeros(eta.shape[:-1] + (6, 6))
    J[..., :3, :3] = rotation(eta)
    J[..., 3:, 3:] = euler_rate_matrix(eta)
    return J


def body_velocity(eta: np.ndarray, eta_dot: np.ndarray) -> np.ndarray:
    """nu = J(eta)^-1 eta_dot (Eq. 2.1 solved for nu): the body velocity of a pose's rate; (..., 6) -> (..., 6)."""
    return np.linalg.solve(jacobian(eta), np.asarray(eta_dot, dtype=float)[..., None])[..., 0]


def jacobian_dot(eta: np.ndarray, eta_dot: np.ndarray) -> np.ndarray:
    """dJ/dt along eta_dot, from the analytic partial derivatives of R and T in phi, theta, psi."""
    eta = np.asarray(eta, dtype=float)
    eta_dot = np.asarray(eta_dot, dtype=float)
    phi, theta, psi = eta[..., 3], eta[..., 4], eta[..., 5]
    dphi, dth, dpsi = eta_dot[..., 3], eta_dot[..., 4], eta_dot[..., 5]
    sf, cf, st, ct, ss, cs = np.sin(phi), np.cos(phi), np.sin(theta), np.cos(theta), np.sin(psi), np.cos(psi)
    z = np.zeros_like(phi)

    def mat(rows):
        return np.stack([np.stack(r, -1) for r in rows], -2)

    dR_dphi = mat([[z, ss * sf + cs * st * cf, ss * cf - cs * sf * st],
                   [z, -cs * sf + cf * st * ss, -cs * cf - st * ss * sf],
                   [z, ct * cf, -ct * sf]])
    dR_dth = mat([[-cs * st, cs * ct * sf, cs * cf * ct],
                  [-ss * st, sf * ct * ss, ct * ss * cf],
                  [-ct, -st * sf, -st * cf]])
    dR_dpsi = mat([[-ss * ct, -cs * cf - ss * st * sf, cs * sf - ss * cf * st],
                   [cs * ct, -ss * cf + sf * st * cs, ss * sf + st * cs * cf],
                   [z, z, z]])
    sec2 = 1.0 / ct**2
    dT_dphi = mat([[z, cf * st / ct, -sf * st / ct], [z, -sf, -cf], [z, cf / ct, -sf / ct]])
    dT_dth = mat([[z, sf * sec2, cf * sec2], [z, z, z], [z, sf * st * sec2, cf * st * sec2]])
    Jd = np.zeros(eta.shape[:-1] + (6, 6))
    Jd[..., :3, :3] = (dR_dphi * dphi[..., None, None] + dR_dth * dth[..., None, None]
                       + dR_dpsi * dpsi[..., None, None])
    Jd[..., 3:, 3:] = dT_dphi * dphi[..., None, None] + dT_dth * dth[..., None, None]
    return Jd


def coriolis(M: np.ndarray, nu: np.ndarray) -> np.ndarray:
    """C(nu) from a symmetric M by Fossen's m2c (ERRATA 5): skew-symmetric, nu^T C nu = 0."""
    nu = np.asarray(nu, dtype=float)
    a = np.einsum("ij,...j->...i", M[:3, :], nu)
    b = np.einsum("ij,...j->...i", M[3:, :], nu)
    C = np.zeros(nu.shape[:-1] + (6, 6))
    C[..., :3, 3:] = -skew(a)
    C[..., 3:, :3] = -skew(a)
    C[..., 3:, 3:] = -skew(b)
    return C


def damping(vehicle: Vehicle, nu: np.ndarray) -> np.ndarray:
    """D(nu) = D_l + D_nl(|nu|), diagonal and positive (Appendix I.3, Eq. 2.10)."""
    nu = np.asarray(nu, dtype=float)
    d = vehicle.linear_damping + vehicle.quadratic_damping * np.abs(nu)
    return d[..., :, None] * np.eye(6)


def restoring(vehicle: Vehicle, eta: np.ndarray) -> np.ndarray:
    """g(eta) as the body-frame wrench of weight at r_g and buoyancy at r_b, negated (Fossen's g(eta)).

    Built from forces and moments (f = R^T [0, 0, W - B]; m = r_g x f_W + r_b x f_B), not from Appendix I.4's
    expanded rows, so it checks them."""
    eta = np.asarray(eta, dtype=float)
    Rt = np.swapaxes(rotation(eta), -1, -2)
    down = np.array([0.0, 0.0, 1.0])
    f_w = Rt @ (down * vehicle.weight)
    f_b = Rt @ (-down * vehicle.buoyancy)
    moment = np.cross(vehicle.center_of_gravity, f_w) + np.cross(vehicle.center_of_buoyancy, f_b)
    return -np.concatenate([f_w + f_b, moment], axis=-1)


def acceleration(vehicle: Vehicle, eta: np.ndarray, nu: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """nu_dot = M^-1 (tau - C(nu) nu - D(nu) nu - g(eta)) (Eq. 2.7, tau including any disturbance)."""
    M = vehicle.mass_matrix
    rhs = (tau - np.einsum("...ij,...j->...i", coriolis(M, nu) + damping(vehicle, nu), nu)
           - restoring(vehicle, eta))
    return np.linalg.solve(M, rhs[..., None])[..., 0]
