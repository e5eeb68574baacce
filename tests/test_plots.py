"""The figures: the thinning of long series keeps what a figure can show; a heading is drawn without wrap jumps."""

from __future__ import annotations

import numpy as np

from rov_mav.offline.plots import BUCKETS, _envelope, _on_reference_branch


def test_a_long_series_is_drawn_from_its_buckets_extremes_in_time_order():
    t = np.linspace(0.0, 3600.0, 360_001)                  # an hour at 100 Hz
    rng = np.random.default_rng(3)
    y = np.sin(t / 30.0) + 0.01 * rng.standard_normal(t.size)
    y[123_457], y[300_001] = 9.0, -9.0                      # one-sample spikes
    y[5_000:5_010] = np.nan
    tt, yy = _envelope(t, y)
    assert tt.size <= 2 * BUCKETS + 2 * t.size // BUCKETS and np.all(np.diff(tt) > 0)
    assert np.nanmax(yy) == 9.0 and np.nanmin(yy) == -9.0
    # every bucket's own extremes are there: the drawn series' envelope is the series'
    size = t.size // BUCKETS
    for k in rng.integers(0, BUCKETS, 20):
        bucket = y[k * size:(k + 1) * size]
        inside = (tt >= t[k * size]) & (tt <= t[(k + 1) * size - 1])
        assert np.nanmax(yy[inside]) == np.nanmax(bucket) and np.nanmin(yy[inside]) == np.nanmin(bucket)


def test_a_short_series_is_drawn_whole():
    t = np.arange(10.0)
    assert _envelope(t, t ** 2)[1].tolist() == (t ** 2).tolist()


def test_a_heading_is_drawn_on_its_references_branch_across_the_wrap():
    """A vehicle turning through south (its heading wrapped from +pi to -pi) against an unwrapped reference of
    1.5 turns: drawn as the reference plus the wrapped error, no line crosses the figure."""
    reference = np.linspace(0.0, 3.0 * np.pi, 500)
    vehicle = (reference + 0.02 * np.sin(np.arange(500)) + np.pi) % (2 * np.pi) - np.pi
    drawn = _on_reference_branch(vehicle, reference)
    assert np.abs(drawn - reference).max() < 0.021
    assert np.abs(np.diff(drawn)).max() < 0.1
