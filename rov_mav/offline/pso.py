"""Particle swarm optimization (Sec. II.v, Eqs. 2.30-2.31): global-best swarm, vectorised over (particles, dims).

The report leaves w, c1, c2 open (ERRATA). Defaults are Clerc and Kennedy's constriction coefficients (2002):
chi = 0.7298 for phi = c1 + c2 = 4.1 gives w = chi and c1 = c2 = chi * 2.05 = 1.49618, the setting of the
standard PSO (SPSO 2007) for which a particle's dynamics provably converge, so the swarm neither explodes nor
needs the optimizer itself tuned.

Stated choices:
- r1, r2 of Eq. 2.30 are drawn uniformly in [0, 1) per particle *and* per dimension.
- Velocity clamping: |v_d| <= velocity_clamp * (upper_d - lower_d) after Eq. 2.30.
- Bounds: after Eq. 2.31 a coordinate outside [lower_d, upper_d] is set onto the bound and its velocity to zero
  (absorbing walls), so every evaluated position lies in the box.
- Initial positions are uniform in the box, initial velocities zero.
- One iteration is one evaluation of the whole swarm: `iterations` x `particles` objective evaluations in all.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

Objective = Callable[[np.ndarray], np.ndarray]   # positions (P, D) -> costs (P,)


@dataclass(frozen=True)
class PSOOptions:
    """The optimizer's design parameters (Eq. 2.30) and the swarm size."""

    particles: int = 100
    iterations: int = 100
    w: float = 0.7298             # inertia
    c1: float = 1.49618           # cognitive (personal best) acceleration
    c2: float = 1.49618           # social (global best) acceleration
    velocity_clamp: float = 0.2   # max speed per iteration as a fraction of the box width (>= 5 iterations to cross)

    def __post_init__(self):
        if self.particles < 1 or self.iterations < 1:
            raise ValueError("particles and iterations must be at least 1")
        if self.velocity_clamp <= 0:
            raise ValueError("velocity_clamp must be positive")


@dataclass(frozen=True)
class PSOResult:
    best_position: np.ndarray     # (D,)
    best_cost: float
    cost_history: np.ndarray      # (iterations,) global best cost after each iteration
    position_history: np.ndarray  # (iterations, D) global best position after each iteration


def minimize(objective: Objective, lower: np.ndarray, upper: np.ndarray, options: PSOOptions = PSOOptions(),
             seed: int = 0, callback: Callable[[int, float], bool | None] | None = None) -> PSOResult:
    """Minimise `objective` over the box [lower, upper] (D,); the same seed gives the same run.

    callback(iteration, best_cost) is called after each iteration (e.g. a progress bar); when it returns True the
    search ends there (a time budget spent), with the best found so far and the history of the iterations run."""
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    if lower.shape != upper.shape or lower.ndim != 1 or np.any(upper <= lower):
        raise ValueError("bounds must be two (D,) arrays with lower < upper")
    rng = np.random.default_rng(seed)
    shape = (options.particles, lower.size)
    v_max = options.velocity_clamp * (upper - lower)
    x = lower + rng.random(shape) * (upper - lower)
    v = np.zeros(shape)
    p_best, p_cost = x.copy(), np.full(options.particles, np.inf)
    costs, positions = np.empty(options.iterations), np.empty((options.iterations, lower.size))
    for it in range(options.iterations):
        if it > 0:
            g_best = positions[it - 1]
            r1, r2 = rng.random(shape), rng.random(shape)
            v = options.w * v + options.c1 * r1 * (p_best - x) + options.c2 * r2 * (g_best - x)   # Eq. 2.30
            np.clip(v, -v_max, v_max, out=v)
            x = x + v                                                                            # Eq. 2.31
            outside = (x < lower) | (x > upper)
            x = np.clip(x, lower, upper)
            v[outside] = 0.0
        cost = np.asarray(objective(x), float)
        better = cost < p_cost
        p_best[better], p_cost[better] = x[better], cost[better]
        best = int(np.argmin(p_cost))
        costs[it], positions[it] = p_cost[best], p_best[best]
        if callback is not None and callback(it + 1, float(costs[it])):
            costs, positions = costs[:it + 1], positions[:it + 1]
            break
    return PSOResult(positions[-1].copy(), float(costs[-1]), costs, positions)
