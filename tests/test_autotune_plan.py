"""Autotune's box (rov_mav.mission.autotune_plan): the excitation moved to the vehicle keeps its shape and stays in
the box, the check square lies inside it, the limits keep every run within MAX_EXCURSION of the box, and what does
not fit is refused in one line."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from rov_mav import shipped
from rov_mav.config import ConfigError
from rov_mav.mission.autotune_plan import (
    MAX_EXCURSION,
    SURFACE_CLEARANCE,
    check_leg,
    extent,
    hold_here,
    moved_excitation,
    outside,
)
from rov_mav.mission.missions import load_mission, mission_from_dict

SOURCE = shipped.resolve("mission", "identify")
SIZE = np.array([3.0, 3.0, 1.5])


@pytest.fixture(scope="module")
def excitation():
    return yaml.safe_load(open(SOURCE)), load_mission(SOURCE)


@pytest.mark.parametrize("start", [(0.0, 0.0, 1.2), (-37.5, 112.25, 8.0)])
def test_the_moved_excitation_is_the_shipped_one_shifted_to_the_start_and_inside_the_box(excitation, start):
    spec, mission = excitation
    moved, box = moved_excitation(spec, mission, np.array(start), SIZE)
    flown = mission_from_dict(moved, "moved")
    t = np.linspace(0.0, mission.duration, 2001)
    shift = np.array(start) - mission.start_pose[:3]
    np.testing.assert_allclose(flown.reference(t)[:, :3], mission.reference(t)[:, :3] + shift, atol=2e-3)
    np.testing.assert_allclose(flown.reference(t)[:, 3:], mission.reference(t)[:, 3:], atol=1e-9)
    assert outside(flown, box) == 0.0 and np.allclose(box.size, SIZE)
    assert flown.limits.max_tracking_error == MAX_EXCURSION
    assert flown.limits.max_depth == pytest.approx(box.high[2] + MAX_EXCURSION, abs=1e-3)


def test_the_check_square_lies_inside_the_box_and_the_dry_runs_hold_is_where_the_vehicle_is(excitation):
    spec, mission = excitation
    moved, box = moved_excitation(spec, mission, np.array([4.0, -2.0, 1.5]), SIZE)
    square = mission_from_dict(check_leg(box), "check")
    low, high = extent(square)
    assert outside(square, box) == 0.0 and np.allclose(high[:2] - low[:2], 2.0, atol=1e-6)
    assert 50.0 < square.duration < 80.0
    hold = mission_from_dict(hold_here(np.array([4.0, -2.0, 1.5, 0.3]), SIZE, moved["limits"]), "hold")
    np.testing.assert_allclose(hold.start_pose, [4.0, -2.0, 1.5, 0.0, 0.0, 0.3], atol=1e-3)
    assert hold.limits.max_depth == pytest.approx(1.5 + SIZE[2] + MAX_EXCURSION)
    assert hold.limits.max_thrust == moved["limits"]["max_thrust"] and hold.limits.max_tracking_error >= 100.0


def test_outside_measures_how_far_a_reference_leaves_the_box(excitation):
    spec, mission = excitation
    _, box = moved_excitation(spec, mission, np.array([0.0, 0.0, 1.5]), SIZE)
    smaller = type(box)(box.low + np.array([0.0, 0.0, 0.2]), box.high)
    assert outside(mission, smaller) == pytest.approx(0.2 - (extent(mission)[0][2] - box.low[2]), abs=1e-3)


def test_a_box_too_small_or_a_start_too_shallow_is_refused_in_one_line(excitation):
    spec, mission = excitation
    with pytest.raises(ConfigError, match=r"needs 2\.5 x 2\.3 x 1\.4 m; --box 2,3,1\.5 is smaller"):
        moved_excitation(spec, mission, np.array([0.0, 0.0, 1.5]), np.array([2.0, 3.0, 1.5]))
    with pytest.raises(ConfigError, match=f"at least {0.4 + SURFACE_CLEARANCE:.1f} m deep"):
        moved_excitation(spec, mission, np.array([0.0, 0.0, 0.5]), SIZE)
    _, box = moved_excitation(spec, mission, np.array([0.0, 0.0, 1.5]), np.array([2.6, 2.6, 1.5]))
    with pytest.raises(ConfigError, match="no room for the check square"):
        check_leg(type(box)(box.low, box.low + np.array([1.5, 1.5, 1.5])))
