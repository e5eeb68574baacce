"""ArduSub's own controllers measured against their logged targets: the stretches and the figures."""

from __future__ import annotations

import numpy as np
import pytest

from rov_mav.review.controller_tracking import Errors, angle_error_deg, armed_stretches, figures

MANUAL, STABILIZE, ALT_HOLD, SURFTRAK = 19, 0, 2, 21


def test_stretches_are_armed_and_of_one_mode_each():
    wall = np.array([0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
    armed = np.array([False, True, True, True, False, True, True])
    mode = np.array([MANUAL, MANUAL, ALT_HOLD, ALT_HOLD, ALT_HOLD, SURFTRAK, SURFTRAK])
    stretches = armed_stretches(wall, armed, mode, end=9.0)
    assert [(s.mode, s.start, s.end) for s in stretches] == [(MANUAL, 1.0, 2.0), (ALT_HOLD, 2.0, 4.0),
                                                             (SURFTRAK, 5.0, 9.0)]


def test_a_figure_counts_only_where_its_mode_holds_the_target():
    t = np.linspace(0.0, 10.0, 101)
    depth = Errors(t, np.where(t < 5.0, 10.0, 0.1 * np.sin(t)))       # MANUAL's large "error" is no error at all
    height = Errors(t, np.full_like(t, 0.2))
    stretches = armed_stretches(np.array([0.0, 5.0]), np.array([True, True]), np.array([MANUAL, SURFTRAK]), 10.0)
    out = figures(stretches, {"depth_m": depth, "height_above_bottom_m": height})
    assert [s["mode"] for s in out] == ["SURFTRAK"]
    inside = (t >= 5.0) & (t < 10.0)
    assert out[0]["errors"]["depth_m"]["rms"] == pytest.approx(np.sqrt(np.mean((0.1 * np.sin(t[inside])) ** 2)))
    assert out[0]["errors"]["height_above_bottom_m"]["max"] == pytest.approx(0.2)
    for figure in out[0]["errors"].values():
        assert figure["rms"] <= figure["max"] and figure["samples"] == inside.sum()


def test_stabilize_holds_attitude_not_depth():
    t = np.linspace(0.0, 4.0, 41)
    stretches = armed_stretches(np.array([0.0]), np.array([True]), np.array([STABILIZE]), 4.0)
    out = figures(stretches, {"depth_m": Errors(t, np.ones_like(t)), "roll_deg": Errors(t, np.ones_like(t))})
    assert set(out[0]["errors"]) == {"roll_deg"}


def test_a_heading_error_is_the_short_way_round():
    assert angle_error_deg(np.array([359.0, 1.0, 180.0]), np.array([1.0, 359.0, -180.0])).tolist() == [-2.0, 2.0, 0.0]


def test_the_position_controllers_velocity_errors_are_the_size_of_the_horizontal_one_and_the_vertical_one():
    """PSCN/PSCE/PSCD columns (m, m/s) as the record reader gives them: the horizontal velocity error is the length
    of (TVN - VN, TVE - VE), PSCE brought to PSCN's times; the vertical one TVD - VD with its sign."""
    from rov_mav.review.controller_tracking import dataflash_errors

    t_us = np.arange(0, 2_000_000, 100_000, dtype=float)
    zero = np.zeros_like(t_us)
    north = {"TimeUS": t_us, "TPN": zero, "PN": zero, "TVN": np.full_like(t_us, 0.3), "VN": zero}
    east = {"TimeUS": t_us + 50_000, "TPE": zero, "PE": zero, "TVE": zero, "VE": np.full_like(t_us, 0.4)}
    down = {"TimeUS": t_us, "TVD": np.full_like(t_us, -0.2), "VD": np.full_like(t_us, 0.1)}
    out = dataflash_errors({"PSCN": north, "PSCE": east, "PSCD": down})
    np.testing.assert_allclose(out["horizontal_velocity_mps"].error, 0.5)
    np.testing.assert_allclose(out["vertical_velocity_mps"].error, -0.3)
    np.testing.assert_allclose(out["horizontal_m"].error, 0.0)
