"""The bottom, the ice and the echo sounder of the built-in vehicle: the geometry of a surface, what a cone of rays
sees of it, and the sounder's errors against its figures."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rov_mav.config import ConfigError
from rov_mav.model.navigation import NavigationError, parse_navigation
from rov_mav.model.seafloor import Surface, parse_surface
from sim_bridge.navigation.attached import attached_sensors
from sim_bridge.navigation.echo_sounder import DOWN, SOURCE, UP, EchoSounder

LEVEL = np.zeros(6)


def pose(north=0.0, east=0.0, depth=6.0, roll=0.0, pitch=0.0, yaw=0.0) -> np.ndarray:
    return np.array([north, east, depth, roll, pitch, yaw])


# -- the surface ----------------------------------------------------------------------------------------------


def test_a_slope_rises_along_its_heading_and_not_across_it():
    floor = Surface(depth=10.0, slope=0.1, heading=math.radians(90))     # rising toward the east
    assert floor.depth_at(0.0, 20.0) == pytest.approx(8.0)
    assert floor.depth_at(35.0, 0.0) == pytest.approx(10.0)
    assert floor.depth_at(0.0, -20.0) == pytest.approx(12.0)


def test_steps_and_a_profile_are_laid_along_the_heading_and_held_beyond_their_ends():
    floor = parse_surface({"profile": [[0, 8.0], [10, 9.0], [20, 7.0]], "steps": [[15, 0.5]]}, "seafloor")
    along = np.array([-5.0, 0.0, 5.0, 14.9, 15.0, 20.0, 40.0])
    np.testing.assert_allclose(floor.depth_at(along, 0.0), [8.0, 8.0, 8.5, 8.02, 7.5, 6.5, 6.5], atol=1e-9)


def test_the_relief_has_the_rms_asked_for_and_the_seed_picks_it():
    rng = np.random.default_rng(0)
    north, east = rng.uniform(-300, 300, (2, 40000))
    rough = Surface(depth=10.0, relief=0.25, wavelength=2.0, seed=3)
    relief = rough.depth_at(north, east) - 10.0
    assert np.sqrt(np.mean(relief ** 2)) == pytest.approx(0.25, rel=0.05)
    assert abs(np.mean(relief)) < 0.01
    same, other = Surface(depth=10.0, relief=0.25, wavelength=2.0, seed=3), Surface(depth=10.0, relief=0.25,
                                                                                    wavelength=2.0, seed=4)
    assert same.depth_at(1.0, 2.0) == rough.depth_at(1.0, 2.0) != other.depth_at(1.0, 2.0)


@pytest.mark.parametrize("block, words", [
    ({"profile": [[0, 8.0]]}, "two or more"),
    ({"profile": [[0, 8.0], [0, 9.0]]}, "distances increasing"),
    ({"slope": 2.0}, "slope"),
    ({"depht": 3.0}, "depht"),
])
def test_a_bad_surface_is_refused_in_one_line(block, words):
    with pytest.raises(ConfigError) as error:
        parse_surface(block, "environment: seafloor")
    assert words in str(error.value) and "\n" not in str(error.value)


# -- what the cone sees ---------------------------------------------------------------------------------------


def test_over_a_flat_bottom_the_range_is_the_height_until_the_tilt_leaves_the_cone():
    sounder = EchoSounder("ideal", 0, Surface(depth=8.0), None)
    half = sounder.figures.beam / 2
    assert sounder.nearest(pose())[0] == pytest.approx(2.0)
    assert sounder.nearest(pose(roll=0.5 * half))[0] == pytest.approx(2.0, rel=0.005)   # a ray near the vertical
    for tilt in (half + 0.1, half + 0.3):
        assert sounder.nearest(pose(pitch=tilt))[0] == pytest.approx(2.0 / math.cos(tilt - half), rel=1e-6)


def test_on_a_slope_the_nearest_return_is_toward_the_rise():
    """A 30 % slope (16.7 degrees, more than the half beam): the nearest return is the edge ray toward the rise,
    shorter than the vertical height and longer than the distance along the slope's normal."""
    floor = Surface(depth=8.0, slope=0.3)
    sounder = EchoSounder("ideal", 0, floor, None)
    distance, spread = sounder.nearest(pose())
    normal = 2.0 * math.cos(math.atan(0.3))
    half = sounder.figures.beam / 2
    edge = 2.0 / (math.cos(half) + 0.3 * math.sin(half))        # depth(x) = 8 - 0.3 x along the ray
    assert normal < distance < 2.0 and distance == pytest.approx(edge, rel=1e-6) and spread > 0.1


def test_looking_up_it_sees_the_ice_or_else_the_surface():
    ice = Surface(depth=1.5)
    assert EchoSounder({"looking": "up"}, 0, None, ice).nearest(pose(depth=4.0))[0] == pytest.approx(2.5)
    assert EchoSounder({"looking": "up"}, 0, None, None).nearest(pose(depth=4.0))[0] == pytest.approx(4.0)
    assert EchoSounder("ideal", 0, None, ice).nearest(pose(depth=4.0))[0] == math.inf    # down, no bottom


# -- the sounder's errors -------------------------------------------------------------------------------------


def soundings(value, floor, seconds: float, depth: float = 6.0, seed: int = 0):
    sounder = EchoSounder(value, seed, floor, None)
    out = []
    for k in range(int(seconds / 0.01)):
        out += sounder.sample(k * 0.01, pose(depth=depth), LEVEL)
    return sounder, out


def test_the_ideal_sounder_reads_the_truth_at_its_rate_and_the_ping_near_it():
    floor = Surface(depth=8.0)
    _, ideal = soundings("ideal", floor, 20.0)
    assert len(ideal) == pytest.approx(20.0 * 9.4, abs=2)
    assert all(s.distance == pytest.approx(2.0) and s.confidence == 100 for s in ideal)
    sounder, ping = soundings("ping", floor, 200.0)
    f = sounder.figures
    noise = f.noise + f.noise_per_range * 2.0
    locked = np.array([abs(s.distance - 2.0) < 5 * noise for s in ping if s.t > 1.0])
    good = np.array([s.distance for s in ping if abs(s.distance - 2.0) < 5 * noise and s.t > 1.0])
    assert locked.mean() > 0.97                # the rest: false locks and the pings after them
    assert 0.2 * noise < np.std(good) < noise and abs(np.mean(good) - 2.0) < 0.002   # the tracking filter smooths


def test_dropouts_and_false_locks_come_at_their_rates_and_say_so_in_the_confidence():
    floor = Surface(depth=8.0)
    value = {"dropout_probability": 0.02, "dropout_duration": 1.0, "false_lock_probability": 0.01,
             "false_lock_duration": 1.0}
    _, out = soundings(value, floor, 600.0)
    dropped = np.array([s.confidence == 0 for s in out])
    locked = np.array([s.distance < 1.85 and s.confidence > 0 for s in out])
    # a dropout starts at 2 % of pings and lasts 1 s (9.4 pings): about 16 % of the time without confidence
    assert 0.08 < dropped.mean() < 0.25
    assert 0.03 < locked.mean() < 0.15
    assert all(s.distance > 0.3 * 2.0 - 0.1 for s in out)
    assert any(s.confidence >= 90 for s, lock in zip(out, locked) if lock)     # some false locks pass the gate


def test_out_of_range_reads_no_confidence():
    _, deep = soundings({"max_range": 5.0}, Surface(depth=20.0), 3.0)
    _, close = soundings("ideal", Surface(depth=6.1), 3.0)
    assert all(s.confidence == 0 for s in deep) and all(s.confidence == 0 for s in close)
    assert all(s.distance == pytest.approx(0.3) for s in close)


def test_the_link_carries_it_as_bluos_ping_service_does():
    sounder, out = soundings("ideal", Surface(depth=8.0), 1.0)
    (msg, source), = sounder.messages(out[0], 123456)
    assert source == SOURCE == (1, 194)
    assert (msg.min_distance, msg.max_distance, msg.current_distance, msg.type, msg.id) == (20, 12000, 200, 1, 1)
    assert (msg.orientation, msg.covariance, msg.signal_quality, msg.time_boot_ms) == (DOWN, 255, 100, 123456)
    assert msg.horizontal_fov == pytest.approx(0.52) and msg.vertical_fov == pytest.approx(0.52)
    zero = type(out[0])(**{**out[0].__dict__, "confidence": 0})
    assert sounder.messages(zero, 0)[0][0].signal_quality == 1          # 0 is sent as 1, "invalid"
    up = EchoSounder({"looking": "up"}, 0, None, None)
    assert up.orientation == UP


def test_the_sounder_is_a_navigation_section_any_preset_may_carry():
    nav = parse_navigation({"preset": "ideal", "echo_sounder": "ping"})
    assert nav.ideal and len(attached_sensors(nav, 0)) == 1
    with pytest.raises(NavigationError, match="unknown section 'echo_sounderr'"):
        attached_sensors(parse_navigation({"preset": "dvl", "echo_sounderr": "ping"}), 0)
    with pytest.raises(NavigationError, match="unknown preset 'pong'"):
        attached_sensors(parse_navigation({"echo_sounder": "pong"}), 0)
    with pytest.raises(NavigationError, match="rate"):
        attached_sensors(parse_navigation({"echo_sounder": {"rate": -1}}), 0)
