"""Thrust along the allocation's null space that keeps every thruster out of its dead band.

Eight thrusters in six degrees of freedom leave a null space: thrust patterns with no net wrench (on a vectored
BlueROV2, the four horizontal thrusters all pushing along their own axis, and the vertical ones in a cross pattern).
Near a hover the allocated thrusts are tenths of a newton, inside or at the edge of every thruster's dead band, where
no PWM gives the force asked (ArduPilot SITL's thrusters jump from 0 to 0.22 N at 1526 us; a T200 gives almost
nothing until ~30 us from neutral). Small moments are then produced by thrusters switching on and off. Adding a null
pattern so that every thruster pushes at least `floor` N either way puts them where force is a smooth function of PWM,
and changes nothing in the wrench.

The null vectors are made sparse (one per independent group of thrusters where the geometry allows), and for each the
shift is the smallest that keeps its thrusters at least `floor` from zero, on the side (sign) the previous tick used
while that side has one: no chattering between the two signs a pattern could take.
"""

from __future__ import annotations

import numpy as np

TOLERANCE = 1e-9


def sparse_null_vectors(matrix: np.ndarray) -> list[np.ndarray]:
    """A basis of the null space of `matrix` (6, n), each vector scaled to a largest entry of 1 and made sparse: for
    each thruster, the null vector with a zero there; the sparsest independent ones are kept."""
    _, singular, vt = np.linalg.svd(matrix)
    rank = int(np.sum(singular > TOLERANCE * singular[0]))
    basis = vt[rank:].T                                          # (n, k)
    k = basis.shape[1]
    if k == 0:
        return []
    candidates = [basis[:, j] for j in range(k)]
    if k == 2:
        for row in basis:
            if np.linalg.norm(row) > TOLERANCE:
                candidates.append(basis @ np.array([-row[1], row[0]]))
    candidates = [np.where(np.abs(v) < 1e-6 * np.abs(v).max(), 0.0, v / np.abs(v).max()) for v in candidates]
    candidates.sort(key=lambda v: int(np.count_nonzero(v)))
    chosen: list[np.ndarray] = []
    for v in candidates:
        if np.linalg.matrix_rank(np.array(chosen + [v]), tol=1e-6) == len(chosen) + 1:
            chosen.append(v)
        if len(chosen) == k:
            break
    return chosen


def _shift(f: np.ndarray, n: np.ndarray, floor: np.ndarray, previous: float) -> float:
    """The smallest alpha on the side of `previous` (0 counts on both) with |f_i + alpha n_i| >= floor_i wherever
    n_i != 0; if that side has none, the one nearest `previous`."""
    support = np.flatnonzero(n)
    # |f + a n| < floor excludes a from an open interval per thruster
    ends = np.sort(np.stack([(-floor[support] - f[support]) / n[support],
                             (floor[support] - f[support]) / n[support]]), axis=0)
    candidates = np.concatenate([[0.0, previous], ends.ravel()])

    clear = np.abs(f[support] + candidates[:, None] * n[support]) >= floor[support] - 1e-9
    feasible = candidates[clear.all(axis=1)].tolist()
    same_side = [a for a in feasible if a * previous >= 0.0]
    if same_side:
        return min(same_side, key=abs)
    return min(feasible, key=lambda a: abs(a - previous))


class Pretension:
    """`apply(thrusts)` -> the thrusts plus null-space patterns, each thruster at least `floor` N from zero."""

    def __init__(self, matrix: np.ndarray, floor: np.ndarray):
        self.vectors = sparse_null_vectors(np.asarray(matrix, dtype=float))
        self.floor = np.asarray(floor, dtype=float)
        self.shifts = np.zeros(len(self.vectors))

    def apply(self, thrusts: np.ndarray) -> np.ndarray:
        out = np.asarray(thrusts, dtype=float).copy()
        for j, n in enumerate(self.vectors):
            self.shifts[j] = _shift(out, n, self.floor, self.shifts[j])
            out = out + self.shifts[j] * n
        return out

    def reset(self) -> None:
        self.shifts[:] = 0.0
