"""PSO (Eqs. 2.30-2.31) on analytic functions with known optima: convergence, seeds, bounds, velocity clamp."""

from __future__ import annotations

import numpy as np
import pytest

from rov_mav.offline.pso import PSOOptions, minimize


def sphere(x: np.ndarray) -> np.ndarray:
    return np.sum(x**2, axis=1)


def rosenbrock(x: np.ndarray) -> np.ndarray:
    return np.sum(100.0 * (x[:, 1:] - x[:, :-1] ** 2) ** 2 + (1.0 - x[:, :-1]) ** 2, axis=1)


class Recorder:
    """An objective that keeps every swarm it was asked to evaluate."""

    def __init__(self, f):
        self.f, self.swarms = f, []

    def __call__(self, x):
        self.swarms.append(x.copy())
        return self.f(x)


def test_sphere_12d_converges_to_the_origin():
    result = minimize(sphere, np.full(12, -5.0), np.full(12, 10.0), PSOOptions(particles=30, iterations=300))
    assert result.best_cost < 1e-8
    np.testing.assert_allclose(result.best_position, 0.0, atol=1e-4)


@pytest.mark.parametrize("seed", [0, 1])
def test_rosenbrock_12d_converges_to_all_ones(seed):
    result = minimize(rosenbrock, np.full(12, -5.0), np.full(12, 10.0),
                      PSOOptions(particles=50, iterations=20000), seed=seed)
    assert result.best_cost < 1e-4
    np.testing.assert_allclose(result.best_position, 1.0, atol=0.01)


def test_best_cost_never_increases_and_matches_the_best_position():
    result = minimize(rosenbrock, np.full(12, -5.0), np.full(12, 10.0), PSOOptions(particles=20, iterations=50))
    assert np.all(np.diff(result.cost_history) <= 0)
    np.testing.assert_allclose(rosenbrock(result.position_history), result.cost_history)
    assert result.best_cost == result.cost_history[-1]


def test_the_seed_makes_runs_identical_and_different_seeds_differ():
    box = (np.full(12, -5.0), np.full(12, 10.0))
    a = minimize(rosenbrock, *box, PSOOptions(particles=20, iterations=40), seed=7)
    b = minimize(rosenbrock, *box, PSOOptions(particles=20, iterations=40), seed=7)
    c = minimize(rosenbrock, *box, PSOOptions(particles=20, iterations=40), seed=8)
    np.testing.assert_array_equal(a.position_history, b.position_history)
    np.testing.assert_array_equal(a.cost_history, b.cost_history)
    assert not np.array_equal(a.position_history, c.position_history)


def test_every_evaluated_position_is_inside_the_box_and_the_optimum_outside_is_found_on_its_edge():
    lower, upper = np.linspace(-3.0, -1.0, 12), np.linspace(1.0, 4.0, 12)
    target = np.where(np.arange(12) % 2 == 0, 9.0, -9.0)            # outside the box in every coordinate
    f = Recorder(lambda x: np.sum((x - target) ** 2, axis=1))
    result = minimize(f, lower, upper, PSOOptions(particles=15, iterations=100), seed=3)
    swarms = np.array(f.swarms)
    assert swarms.shape == (100, 15, 12)                             # one evaluation of the swarm per iteration
    assert np.all(swarms >= lower) and np.all(swarms <= upper)
    np.testing.assert_allclose(result.best_position, np.where(target > 0, upper, lower))


def test_a_particle_moves_at_most_the_velocity_clamp_per_iteration():
    lower, upper = np.zeros(12), np.linspace(1.0, 12.0, 12)
    f = Recorder(rosenbrock)
    minimize(f, lower, upper, PSOOptions(particles=25, iterations=30, velocity_clamp=0.05), seed=5)
    steps = np.abs(np.diff(np.array(f.swarms), axis=0))
    assert np.all(steps <= 0.05 * (upper - lower) + 1e-12)
    assert steps.max() > 0.04 * (upper - lower).min()                # the clamp is reached, not just respected


def test_without_acceleration_the_swarm_does_not_move():
    """Eq. 2.30 with c1 = c2 = 0 and zero initial velocity: v stays 0, so x never changes (Eq. 2.31)."""
    f = Recorder(sphere)
    minimize(f, np.full(3, -1.0), np.full(3, 1.0), PSOOptions(particles=4, iterations=5, c1=0.0, c2=0.0))
    for swarm in f.swarms[1:]:
        np.testing.assert_array_equal(swarm, f.swarms[0])


@pytest.mark.parametrize("lower, upper", [(np.zeros(3), np.zeros(3)), (np.ones(3), np.zeros(3)),
                                          (np.zeros(3), np.ones(4))])
def test_bad_bounds_are_refused(lower, upper):
    with pytest.raises(ValueError):
        minimize(sphere, lower, upper)


def test_a_callback_that_says_stop_ends_the_search_with_the_iterations_run():
    full = minimize(sphere, np.full(4, -5.0), np.full(4, 10.0), PSOOptions(particles=20, iterations=50), seed=3)
    seen = []
    stopped = minimize(sphere, np.full(4, -5.0), np.full(4, 10.0), PSOOptions(particles=20, iterations=50), seed=3,
                       callback=lambda it, best: seen.append(it) or it >= 7)
    assert seen == list(range(1, 8)) and stopped.cost_history.size == 7 and stopped.position_history.shape == (7, 4)
    np.testing.assert_array_equal(stopped.cost_history, full.cost_history[:7])
    assert stopped.best_cost == full.cost_history[6] > full.best_cost
