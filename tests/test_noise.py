"""The offline loop's noise generator: its normals have the normal distribution, body and tails."""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from scipy import stats

from rov_mav.offline import noise


@njit(cache=False)
def _draws(seed, n, normal):
    """n draws of the generator seeded by seed: normals, or uniforms."""
    out, rng = np.empty(n), np.uint64(seed)
    for k in range(n):
        rng, out[k] = noise.normal(rng) if normal else noise.uniform(rng)
    return out


def test_layers_have_equal_areas_and_close_at_the_peak():
    """The ziggurat's construction for R and V: the base layer (the rectangle under f(R) out to R and the tail beyond)
    has the area V, every layer above it (x_i wide, from f(x_i) up to f(x_{i+1})) too, and the top one reaches the
    peak f(0) = 1 with that same area."""
    x, f = noise._EDGES, lambda v: np.exp(-0.5 * v * v)
    R, V = noise.TAIL_START, noise.LAYER_AREA
    assert math.isclose(R * f(R) + math.sqrt(2 * math.pi) * stats.norm.sf(R), V, rel_tol=1e-9)
    np.testing.assert_allclose(x[1:-2] * (f(x[2:-1]) - f(x[1:-2])), V, rtol=1e-9)
    assert math.isclose(x[-2] * (1.0 - f(x[-2])), V, rel_tol=1e-6)


def test_normals_follow_the_normal_distribution_tails_included():
    draws = _draws(11, 2_000_000, True)
    assert stats.kstest(draws, "norm").pvalue > 1e-3
    assert abs(draws.mean()) < 4 / math.sqrt(draws.size)
    assert abs(draws.std() - 1.0) < 0.003
    # beyond the base layer's start (the tail path) and beyond 2 (the wedges): the normal's own probabilities
    for edge in (2.0, noise.TAIL_START, 4.0):
        expected = 2 * stats.norm.sf(edge) * draws.size
        assert abs(np.sum(np.abs(draws) > edge) - expected) < 5 * math.sqrt(expected)
    assert abs(stats.kurtosis(draws)) < 0.02 and abs(stats.skew(draws)) < 0.01


def test_uniforms_cover_the_unit_interval_evenly():
    draws = _draws(3, 500_000, False)
    assert draws.min() >= 0.0 and draws.max() < 1.0
    assert stats.kstest(draws, "uniform").pvalue > 1e-3
