"""A position estimate that jumps is taken in at a flyable pace (`flight.estimate_jumps`), and motion is not a jump."""

from __future__ import annotations

import numpy as np

from rov_mav.flight.estimate_jumps import CATCH_ACCEL, CATCH_UP, EstimateJumps, catch_up_time


def _fly(positions, velocities, dt=0.02):
    guard = EstimateJumps()
    return guard, np.array([guard.steady(k * dt, p, v) for k, (p, v) in enumerate(zip(positions, velocities))])


def test_steady_motion_with_noise_and_a_turn_is_never_a_jump():
    rng = np.random.default_rng(1)
    t = np.arange(0.0, 60.0, 0.02)
    v = np.stack([0.3 * np.cos(0.2 * t), 0.3 * np.sin(0.2 * t), 0.05 * np.ones_like(t)], axis=1)
    p = np.cumsum(v, axis=0) * 0.02 + rng.normal(0.0, 0.01, v.shape)
    guard, seen = _fly(p, v)
    assert guard.jumps == [] and np.allclose(seen, p)


def test_a_one_metre_jump_is_taken_in_at_the_catch_up_pace_and_nothing_faster():
    t = np.arange(0.0, 30.0, 0.02)
    p = np.zeros((t.size, 3))
    p[t >= 5.0] += [0.8, -0.6, 0.0]                       # a reset moves the estimate 1 m; the vehicle is still
    guard, seen = _fly(p, np.zeros_like(p))
    assert len(guard.jumps) == 1 and np.isclose(guard.jumps[0].t, 5.0)
    assert np.allclose(guard.jumps[0].step, [0.8, -0.6, 0.0])
    speed = np.linalg.norm(np.diff(seen, axis=0), axis=1) / 0.02
    assert speed.max() <= CATCH_UP * (1 + 1e-9)           # the law never sees the step, only the pace
    assert np.abs(np.diff(speed)).max() / 0.02 <= CATCH_ACCEL * 2.0   # reached and left gently (no kick)
    done = 5.0 + catch_up_time(1.0)
    assert np.isclose(catch_up_time(1.0), 12.0)
    assert np.allclose(seen[t >= done + 0.1], p[-1], atol=1e-3)      # all of it taken in
    assert not np.allclose(seen[t <= done - 1.0][-1], p[-1], atol=1e-3)
