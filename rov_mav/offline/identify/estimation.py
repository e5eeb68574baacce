"""Small, dense nonlinear estimation: least squares with lower bounds, square systems, instrumental-variables
covariance, collinearity. Normal equations are formed with einsum: the problems are small (tens of parameters), and
this keeps them off BLAS threads, which a loaded machine's contention makes a hundred times slower.
"""

from __future__ import annotations

import numpy as np

MAX_ITERATIONS = 50
STRUCTURAL = 1e-6             # singular value ratio of the column-scaled regressors below which a direction is blind


def _solve(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """x with a x = b (LU: exact whatever the columns' scales, which differ by orders of magnitude here), or the
    least-squares answer where a is exactly singular (a column the data leave at 0)."""
    try:
        return np.linalg.solve(a, b)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(a, b, rcond=None)[0]


def gauss_newton(function, jacobian, theta: np.ndarray, index: np.ndarray) -> np.ndarray:
    """theta with function(theta) = 0 over theta[index] (as many equations as unknowns; jacobian: theta ->
    (len(index), len(index))), by Newton steps halved while they do not reduce |function|; unbounded."""
    theta = theta.copy()
    f = function(theta)
    for _ in range(MAX_ITERATIONS):
        step = _solve(jacobian(theta), -f)
        for _ in range(20):
            trial = theta.copy()
            trial[index] += step
            f_trial = function(trial)
            if f_trial @ f_trial < f @ f:
                break
            step *= 0.5
        else:
            break
        converged = np.all(np.abs(trial[index] - theta[index]) <= 1e-10 * np.maximum(np.abs(theta[index]), 1e-3))
        theta, f = trial, f_trial
        if converged:
            break
    return theta


def levenberg_marquardt(function, jacobian, theta: np.ndarray, index: np.ndarray, lower: np.ndarray) -> np.ndarray:
    """theta with theta[index] minimising |function(theta)|^2 subject to theta >= lower (a parameter at its bound
    that the gradient pushes further out is held there for the step). function: theta -> (n,) residuals;
    jacobian: theta -> (n, len(index))."""
    theta = theta.copy()
    f = function(theta)
    cost = float(f @ f)
    damping = 1e-3
    for _ in range(MAX_ITERATIONS):
        jac = jacobian(theta)
        gradient = np.einsum("ij,i->j", jac, f)
        normal = np.einsum("ij,ik->jk", jac, jac)
        movable = ~((theta[index] <= lower[index]) & (gradient > 0))
        h = normal[np.ix_(movable, movable)]
        while True:
            step = np.zeros(index.size)
            step[movable] = _solve(h + damping * np.diag(np.diag(h)), -gradient[movable])
            trial = theta.copy()
            trial[index] = np.maximum(theta[index] + step, lower[index])
            f_trial = function(trial)
            cost_trial = float(f_trial @ f_trial)
            if cost_trial <= cost or damping > 1e12:
                break
            damping *= 10.0
        if cost_trial > cost:
            break
        converged = cost - cost_trial <= 1e-12 * cost
        theta, f, cost = trial, f_trial, cost_trial
        damping = max(damping / 10.0, 1e-12)
        if converged:
            break
    return theta


def sandwich(jac: np.ndarray, z: np.ndarray) -> np.ndarray:
    """(Z^T J)^-1 Z^T Z (J^T Z)^-1: the instrumental-variables covariance per unit residual variance."""
    inverse = np.linalg.pinv(np.einsum("ij,ik->jk", z, jac))
    return inverse @ np.einsum("ij,ik->jk", z, z) @ inverse.T


def collinearity(jacobian: np.ndarray) -> tuple[np.ndarray | None, np.ndarray, np.ndarray]:
    """(blind, vif, correlation) of the regressors (the Jacobian's columns scaled to unit length): the parameter
    direction the data cannot see at all (or None), each parameter's variance inflation factor 1 / (1 - R_j^2)
    (R_j: how well the other columns reproduce its own) and the parameters' correlations."""
    norms = np.linalg.norm(jacobian, axis=0)
    p = norms.size
    if np.any(norms == 0):
        return (norms == 0).astype(float), np.full(p, np.inf), np.eye(p)
    scaled = jacobian / norms
    normal = np.einsum("ij,ik->jk", scaled, scaled)
    eigenvalues, vectors = np.linalg.eigh(normal)               # singular values squared, ascending
    if eigenvalues[0] < STRUCTURAL**2 * eigenvalues[-1]:
        return vectors[:, 0], np.full(p, np.inf), np.eye(p)
    inverse = np.linalg.inv(normal)
    vif = np.diag(inverse)
    return None, vif, inverse / np.sqrt(np.outer(vif, vif))
