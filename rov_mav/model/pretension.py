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

from rov_mav.model.kernel import compiled

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


@compiled
def _shift(f: np.ndarray, n: np.ndarray, floor: np.ndarray, previous: float) -> float:
    """The smallest alpha on the side of `previous` (0 counts on both) with |f_i + alpha n_i| >= floor_i wherever
    n_i != 0; if that side has none, the one nearest `previous`. The candidates, in order (the first wins a tie):
    0, `previous`, then the ends of the open interval |f_i + alpha n_i| < floor_i excludes for each thruster (the
    lower ends, then the upper ones)."""
    m = f.shape[0]
    same, same_size, found_same = 0.0, np.inf, False
    nearest, nearest_gap = 0.0, np.inf
    for c in range(2 + 2 * m):
        if c == 0:
            a = 0.0
        elif c == 1:
            a = previous
        else:
            i = (c - 2) % m
            if n[i] == 0.0:
                continue
            e1, e2 = (-floor[i] - f[i]) / n[i], (floor[i] - f[i]) / n[i]
            a = max(e1, e2) if c - 2 >= m else min(e1, e2)
        clear = True
        for j in range(m):
            if n[j] != 0.0 and abs(f[j] + a * n[j]) < floor[j] - TOLERANCE:
                clear = False
                break
        if not clear:
            continue
        if a * previous >= 0.0 and abs(a) < same_size:
            same, same_size, found_same = a, abs(a), True
        if abs(a - previous) < nearest_gap:
            nearest, nearest_gap = a, abs(a - previous)
    return same if found_same else nearest


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
