"""Null-space pretension: thrust patterns with no net wrench that keep every thruster off its dead band."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rov_mav.model.pretension import Pretension, sparse_null_vectors
from rov_mav.model.thrusters import allocation_matrix
from rov_mav.model.vehicle import load_vehicle

SITL_VEHICLE = Path(__file__).resolve().parents[1] / "vehicles" / "ardusub_sitl.yaml"


@pytest.fixture(params=[None, SITL_VEHICLE], ids=["bluerov2", "sitl"])
def matrix(request):
    v = load_vehicle(request.param)
    return allocation_matrix(v.thruster_positions, v.thruster_directions)


def test_null_vectors_are_the_horizontal_and_vertical_groups(matrix):
    vectors = sparse_null_vectors(matrix)
    assert len(vectors) == 2
    for n in vectors:
        assert np.allclose(matrix @ n, 0.0, atol=1e-9)
    supports = sorted(tuple(np.flatnonzero(n)) for n in vectors)
    assert supports == [(0, 1, 2, 3), (4, 5, 6, 7)]


def test_every_thruster_reaches_the_floor_and_the_wrench_is_unchanged(matrix):
    floor = np.full(8, 0.3)
    pretension = Pretension(matrix, floor)
    rng = np.random.default_rng(3)
    for _ in range(200):
        f = rng.normal(0.0, rng.choice([0.1, 1.0, 10.0]), 8)
        g = pretension.apply(f)
        assert np.all(np.abs(g) >= floor - 1e-9)
        assert np.allclose(matrix @ g, matrix @ f, atol=1e-9)


def test_the_pattern_keeps_its_sign_and_shrinks_when_it_can(matrix):
    """A slowly changing trim never flips the pattern's sign, and a large command needs no pretension at all."""
    pretension = Pretension(matrix, np.full(8, 0.3))
    signs = set()
    for k in range(500):
        f = 0.2 * np.sin(0.01 * k + np.arange(8))
        pretension.apply(f)
        signs.add(tuple(np.sign(pretension.shifts)))
    assert len(signs) == 1
    pretension.apply(np.array([5.0, 5.0, 5.0, 5.0, 5.0, 5.0, 5.0, 5.0]))
    assert np.allclose(pretension.shifts, 0.0)


def test_a_full_rank_square_allocation_has_nothing_to_add():
    matrix = np.eye(6)
    assert sparse_null_vectors(matrix) == []
    f = np.array([0.01, 0.0, -0.02, 0.0, 0.0, 0.0])
    assert np.array_equal(Pretension(matrix, np.full(6, 0.3)).apply(f), f)
