"""The runner's estimate blend (`flight.state.estimate_blend`): motion the velocity shows passes at once, the position's
corrections below the bandwidth, and a velocity bias is learnt away."""

from __future__ import annotations

import numpy as np
import pytest

from rov_mav.flight.state.estimate_blend import BIAS_RATIO, EstimateBlend

DT = 0.02


def run(blend: EstimateBlend, t, p, v) -> tuple[np.ndarray, np.ndarray]:
    out = [blend.update(tk, pk, vk) for tk, pk, vk in zip(t, p, v)]
    return np.array([o[0] for o in out]), np.array([o[1] for o in out])


def test_consistent_position_and_velocity_pass_unchanged():
    t = np.arange(0, 20, DT)
    v = np.column_stack([0.2 * np.sin(0.5 * t), 0.1 * np.cos(t), 0.05 * np.ones_like(t)])
    p = np.vstack([np.zeros(3), np.cumsum(v, axis=0)[:-1] * DT])     # p is exactly the (Euler) integral of v
    p_out, v_out = run(EstimateBlend(0.5), t, p, v)
    assert np.allclose(v_out, v, atol=1e-12) and np.allclose(p_out, p, atol=1e-12)


def test_a_velocity_bias_is_learnt_and_the_position_settles_on_the_reported_one():
    """The reported velocity is 2 cm/s off the position's rate: the law's velocity becomes the rate and its position
    the reported one (no steady offset), over about L1 / L2 s."""
    bandwidth = 0.5
    t = np.arange(0, 200, DT)
    rate = np.array([0.2, 0.0, 0.0])
    p = t[:, None] * rate
    v = np.tile(rate + [0.0, 0.02, 0.0], (len(t), 1))
    p_out, v_out = run(EstimateBlend(bandwidth), t, p, v)
    settle = BIAS_RATIO / bandwidth                                   # s
    late = t > 4 * settle
    assert np.abs(v_out[late, 1]).max() < 1e-3 and np.abs(p_out[late] - p[late]).max() < 2e-3
    assert np.allclose(v_out[:, 0], 0.2)
    assert np.abs(p_out[:, 1] - p[:, 1]).max() < 0.02 / bandwidth    # never further off than a first-order blend


def test_a_fixs_correction_reaches_the_law_slowly_and_the_velocitys_motion_at_once():
    """A 10 cm correction of the position (the velocity still says at rest) comes in over about 1 / L1 s; a start of
    motion the velocity shows is in the law's velocity at the same sample."""
    blend = EstimateBlend(0.5)
    t = np.arange(0, 10, DT)
    p = np.where(t[:, None] >= 1.0, [0.1, 0.0, 0.0], [0.0, 0.0, 0.0])
    p_out, _ = run(blend, t, p, np.zeros_like(p))
    step = np.diff(p_out[:, 0])
    assert step.max() < 0.1 * 0.5 * DT * 1.01                          # at most L1 e per second
    assert 0.3 < p_out[np.searchsorted(t, 3.0), 0] / 0.1 < 0.8       # about 1 - exp(-1) after 1 / L1 s
    blend = EstimateBlend(0.5)
    _, v_out = run(blend, [0.0, DT], [[0, 0, 0], [0, 0, 0]], [[0, 0, 0], [0.3, 0, 0]])
    assert v_out[1, 0] == pytest.approx(0.3)


def test_zero_bandwidth_is_the_reported_position_and_velocity():
    blend = EstimateBlend(0.0)
    p, v = blend.update(0.0, [1, 2, 3], [0.1, 0.2, 0.3])
    assert p.tolist() == [1, 2, 3] and v.tolist() == [0.1, 0.2, 0.3]
    p, v = blend.update(0.02, [5, 5, 5], [0.1, 0.2, 0.3])
    assert p.tolist() == [5, 5, 5] and v.tolist() == [0.1, 0.2, 0.3]


def test_a_long_gap_restarts_at_the_position():
    blend = EstimateBlend(1.0)
    blend.update(0.0, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0])
    p, v = blend.update(0.02, [0.1, 0.0, 0.0], [0.0, 0.0, 0.0])      # a 10 cm jump: the blend follows slowly
    assert p[0] == pytest.approx(0.0) and v[0] == pytest.approx(0.1, rel=0.01)   # L1 e
    p, v = blend.update(2.0, [0.5, 0.0, 0.0], [0.0, 0.0, 0.0])       # 2 s later: no stale integration
    assert p.tolist() == [0.5, 0.0, 0.0] and v.tolist() == [0.0, 0.0, 0.0]
    with pytest.raises(ValueError):
        EstimateBlend(-1.0)
