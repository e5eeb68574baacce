"""The runner's velocity blend: the law's velocity becomes the rate of the reported position below the bandwidth."""

from __future__ import annotations

import numpy as np
import pytest

from rov_mav.flight.velocity_blend import VelocityBlend

DT = 0.02


def run(blend: VelocityBlend, t: np.ndarray, p: np.ndarray, v: np.ndarray) -> np.ndarray:
    return np.array([blend.update(tk, pk, vk) for tk, pk, vk in zip(t, p, v)])


def test_consistent_position_and_velocity_pass_unchanged():
    t = np.arange(0, 20, DT)
    v = np.column_stack([0.2 * np.sin(0.5 * t), 0.1 * np.cos(t), 0.05 * np.ones_like(t)])
    p = np.cumsum(v, axis=0) * DT                       # p is exactly the (Euler) integral of v
    out = run(VelocityBlend(1.0), t, np.vstack([np.zeros(3), p[:-1]]), v)
    assert np.allclose(out, v, atol=1e-12)


def test_a_velocity_bias_is_removed_at_the_bandwidth():
    """The reported velocity is 2 cm/s off the position's rate: the blend converges to the rate in ~1/L s."""
    bandwidth = 1.0
    t = np.arange(0, 10, DT)
    rate = np.array([0.2, 0.0, 0.0])
    p = t[:, None] * rate
    v = np.tile(rate + [0.0, 0.02, 0.0], (len(t), 1))
    out = run(VelocityBlend(bandwidth), t, p, v)
    bias = out[:, 1]
    assert bias[0] == pytest.approx(0.02)
    k = int(round(1.0 / bandwidth / DT))                 # one time constant
    assert bias[k] == pytest.approx(0.02 * np.exp(-1.0), rel=0.03)
    assert abs(bias[-1]) < 0.02 * 1e-3
    assert np.allclose(out[:, 0], 0.2)


def test_zero_bandwidth_is_the_reported_velocity():
    blend = VelocityBlend(0.0)
    assert blend.update(0.0, [1, 2, 3], [0.1, 0.2, 0.3]).tolist() == [0.1, 0.2, 0.3]
    assert blend.update(0.02, [5, 5, 5], [0.1, 0.2, 0.3]).tolist() == [0.1, 0.2, 0.3]


def test_a_long_gap_restarts_at_the_position():
    blend = VelocityBlend(1.0)
    blend.update(0.0, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0])
    jumped = blend.update(0.02, [0.1, 0.0, 0.0], [0.0, 0.0, 0.0])        # a 10 cm jump: the blend follows slowly
    assert jumped[0] == pytest.approx(0.1)
    after_gap = blend.update(2.0, [0.5, 0.0, 0.0], [0.0, 0.0, 0.0])      # 2 s later: no stale integration
    assert after_gap.tolist() == [0.0, 0.0, 0.0]
    with pytest.raises(ValueError):
        VelocityBlend(-1.0)
