"""The control and adaptation laws in matrix form (ERRATA 2 and 3, docs/errata.md), batched: the statement the
kernel is held to."""

from __future__ import annotations

import numpy as np

from rov_mav.model import dynamics
from rov_mav.model.vehicle import Vehicle
from rov_mav.units import wrap_angle


def tracking_error(eta: np.ndarray, eta_d: np.ndarray) -> np.ndarray:
    """e = eta - eta_d (Eq. 2.13) with the angle errors wrapped to [-pi, pi)."""
    e = np.asarray(eta, float) - eta_d
    e[..., 3:] = wrap_angle(e[..., 3:])
    return e


def control_law(model: Vehicle, k1: np.ndarray, k2: np.ndarray, eta: np.ndarray, nu: np.ndarray,
                ref: np.ndarray, tau_hat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """tau = M J^-1 (eta_dd_d - k1 e_dot - J_dot nu - k2 s) + C nu + D nu + g - tau_hat (ERRATA 2); returns (tau, s)."""
    J = dynamics.jacobian(eta)
    eta_dot = np.einsum("...ij,...j->...i", J, nu)
    e = tracking_error(eta, ref[..., :6])
    e_dot = eta_dot - ref[..., 6:12]
    s = e_dot + k1 * e
    A = np.einsum("...ij,...j->...i", dynamics.jacobian_dot(eta, eta_dot), nu)
    a = ref[..., 12:18] - k1 * e_dot - A - k2 * s
    M = model.mass_matrix
    feedforward = np.einsum("ij,...j->...i", M, np.linalg.solve(J, a[..., None])[..., 0])
    CD = dynamics.coriolis(M, nu) + dynamics.damping(model, nu)
    tau = feedforward + np.einsum("...ij,...j->...i", CD, nu) + dynamics.restoring(model, eta) - tau_hat
    return tau, s


def adaptation_direction(model: Vehicle, eta: np.ndarray, s: np.ndarray) -> np.ndarray:
    """(J M^-1)^T s, so that d(tau_hat)/dt = Gamma (J M^-1)^T s (ERRATA 3, corrected Eq. 2.22)."""
    JMinv = dynamics.jacobian(eta) @ np.linalg.inv(model.mass_matrix)
    return np.einsum("...ji,...j->...i", JMinv, s)
