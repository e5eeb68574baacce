"""A position estimate that jumps is taken in at a flyable pace (`flight.state.estimate_jumps`), and motion is not a
jump: on
steps, and on what the built-in vehicle's EKF3 stand-in reports."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from rov_mav.flight.state.estimate_jumps import CATCH_ACCEL, CATCH_UP, EstimateJumps, catch_up_time
from rov_mav.model.navigation import PRESETS, Ugps
from sim_bridge.navigation.estimator import Estimator
from rov_mav.model.dynamics import attitude_rotation
from sim_bridge.navigation.sensors import ImuSample, Sensors, UgpsFix


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


def _vehicle_estimate(nav, seconds: float, feed) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The built-in vehicle's EKF3 stand-in at 50 Hz, `feed(k, t, estimator)` giving it its sensors: (t, its reported
    position, its reported NED velocity)."""
    est = Estimator(nav, 0.0, np.array([0, 0, 5.0, 0, 0, 0]), np.zeros(6))
    rows = []
    for k in range(1, int(round(seconds / 0.02)) + 1):
        t = k * 0.02
        feed(k, t, est)
        eta, nu = est.output
        rows.append((t, eta[:3].copy(), attitude_rotation(*eta[3:6]) @ nu[:3]))
    return np.array([r[0] for r in rows]), np.array([r[1] for r in rows]), np.array([r[2] for r in rows])


def test_a_fix_after_a_dropout_spread_by_the_ekfs_output_predictor_is_one_jump_taken_in_at_the_pace():
    """10 s without a fix on a biased accelerometer (0.6 m of drift), then a fix at the truth: EKF3's output
    predictor brings the 0.6 m in over about 0.25 s (`sim_bridge.navigation.estimator`), no single sample a large step.
    It is
    one jump, and the law sees the estimate move beyond its own velocity at the catch-up pace at most."""
    nav = replace(PRESETS["ugps"], ugps=replace(Ugps(outlier_probability=0.0, dropout_probability=0.0),
                                                ekf_delay=0.2))

    def feed(k, t, est):
        if k == 500:
            est.feed(UgpsFix(t - 0.4, t, 0.0, 0.0, 0.1, True))
        est.feed(ImuSample(t, 0.02, np.array([0.02 * 0.02, 0, 0]), np.zeros(3), 0.0, 0.0))

    t, p, v = _vehicle_estimate(nav, 16.0, feed)
    assert np.abs(np.diff(p[:, 0])).max() < 0.1                       # spread: no step the old guard would see
    guard = EstimateJumps()
    seen = np.array([guard.steady(ti, pi, vi) for ti, pi, vi in zip(t, p, v)])
    assert len(guard.jumps) == 1 and guard.jumps[0].t == pytest.approx(t[499])
    moved = p[498, 0] - p[560, 0]
    assert -guard.jumps[0].step[0] == pytest.approx(moved, rel=0.2) and moved > 0.4
    beyond = (seen[1:] - seen[:-1] - v[:-1] * 0.02) / 0.02           # the seen position's motion beyond its velocity
    assert np.linalg.norm(beyond, axis=1)[490:].max() <= 1.5 * CATCH_UP


def test_a_still_vehicles_acoustic_fixes_are_never_a_jump():
    """Two minutes of the ugps preset's fixes (3.8 Hz, 10 cm plus 1 % of the range; no outlier, no dropout) on a
    vehicle held still 40 m from the transceiver: the EKF stand-in's corrections are never held."""
    nav = replace(PRESETS["ugps"], ugps=replace(PRESETS["ugps"].ugps, transceiver=(-40.0, 0.0, 0.0),
                                                outlier_probability=0.0, dropout_probability=0.0))
    eta, nu = np.array([0, 0, 5.0, 0, 0, 0]), np.zeros(6)
    sensors = Sensors(nav, 3, eta, nu)

    def feed(k, t, est):
        for item in sensors.sample(t, eta, nu):
            est.feed(item)

    t, p, v = _vehicle_estimate(nav, 120.0, feed)
    guard = EstimateJumps()
    seen = np.array([guard.steady(ti, pi, vi) for ti, pi, vi in zip(t, p, v)])
    assert guard.jumps == [] and np.array_equal(seen, p)
