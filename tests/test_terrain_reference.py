"""An altitude leg's depth made online (`rov_mav.mission.terrain`): the surface's estimate from soundings and the
reference that holds the height within the vehicle's limits; and the mission file's altitude and standoff legs."""

from __future__ import annotations

import numpy as np
import pytest

from rov_mav.config import ConfigError
from rov_mav.mission.missions import mission_from_dict
from rov_mav.mission.terrain import GATE_COUNT, LOST_AFTER, MIN_HEIGHT, SurfaceEstimate, TerrainReference, \
    VerticalLimits

RATE = 10.0                      # Hz of soundings


def ramp_soundings(seconds: float, rise: float, noise: float = 0.0, depth: float = 6.0, seed: int = 0):
    """(t, vehicle depth, range) of a vehicle holding `depth` over a bottom at 8 m rising `rise` m/s."""
    rng = np.random.default_rng(seed)
    for k in range(int(seconds * RATE)):
        t = k / RATE
        yield t, depth, 8.0 - rise * t - depth + noise * rng.standard_normal()


def test_the_estimate_follows_a_rising_bottom_without_lag_and_knows_its_rate():
    estimate = SurfaceEstimate()
    for t, depth, distance in ramp_soundings(30.0, 0.05, noise=0.01):
        estimate.update(t, depth, distance, 100)
    surface, rate = estimate.at(t)
    assert surface == pytest.approx(8.0 - 0.05 * t, abs=0.01) and rate == pytest.approx(-0.05, abs=0.01)
    assert estimate.std < 0.02


def test_a_false_lock_is_held_back_and_a_real_step_taken_after_it_persists():
    estimate = SurfaceEstimate()
    t = 0.0
    for k in range(50):
        t = k / RATE
        estimate.update(t, 6.0, 2.0, 100)
    for k in range(GATE_COUNT - 1):               # kelp: a short lock at 1.2 m
        t += 1 / RATE
        assert not estimate.update(t, 6.0, 1.2, 90)
    assert estimate.at(t)[0] == pytest.approx(8.0, abs=0.01)
    for k in range(GATE_COUNT + 1):               # the bottom stepped up by 0.5 m and stays
        t += 1 / RATE
        estimate.update(t, 6.0, 1.5, 100)
    assert estimate.at(t)[0] == pytest.approx(7.5, abs=0.02)


def test_low_quality_soundings_are_ignored_and_silence_loses_the_surface():
    estimate = SurfaceEstimate()
    estimate.update(0.0, 6.0, 2.0, 100)
    assert not estimate.update(0.1, 6.0, 0.5, 10)
    assert not estimate.lost(LOST_AFTER - 0.01) and estimate.lost(LOST_AFTER + 0.01)


def test_looking_up_the_estimate_is_the_ice_above():
    ice = SurfaceEstimate(looking_up=True)
    ice.update(0.0, 4.0, 1.5, 100)
    assert ice.at(0.0)[0] == pytest.approx(2.5)


def test_the_reference_reaches_its_goal_within_its_limits_and_never_overshoots_far():
    limits = VerticalLimits(climb=0.3, descent=0.2, accel=0.3)
    reference = TerrainReference(6.0, 0.0, limits)
    track = np.array([reference.step(0.02, 4.0) for _ in range(1000)])
    assert track[-1, 0] == pytest.approx(4.0, abs=0.005) and abs(track[-1, 1]) < 0.01
    assert track[:, 1].min() >= -0.3 - 1e-9 and np.abs(track[:, 2]).max() <= 0.3 + 1e-9
    assert track[:, 0].min() > 4.0 - 0.02
    down = TerrainReference(4.0, 0.0, limits)
    assert max(down.step(0.02, 6.0)[1] for _ in range(500)) <= 0.2 + 1e-9


def test_the_goal_keeps_the_floor_on_the_height_and_the_max_depth():
    reference = TerrainReference(5.0, 0.0, VerticalLimits(max_depth=7.0))
    assert reference.goal(8.0, 1.0, False) == pytest.approx(7.0)
    assert reference.goal(10.0, 1.0, False) == pytest.approx(7.0)           # max_depth rules
    free = TerrainReference(5.0, 0.0, VerticalLimits())
    assert free.goal(8.0, 0.1, False) == pytest.approx(8.0 - MIN_HEIGHT)
    assert free.goal(2.0, 1.5, True) == pytest.approx(3.5)                   # under ice


def test_holding_brakes_to_a_stop_and_stays():
    reference = TerrainReference(5.0, -0.3, VerticalLimits(accel=0.3))
    track = np.array([reference.step(0.02, None) for _ in range(200)])
    assert track[-1, 1] == 0.0 and track[-1, 0] == pytest.approx(5.0 - 0.3 ** 2 / (2 * 0.3), abs=0.01)


MISSION = {"name": "t", "start": {"position": [0.0, 0.0, 5.0]}}


def test_a_mission_says_which_legs_hold_an_altitude_or_a_standoff():
    mission = mission_from_dict({**MISSION, "path": [{"goto": [10.0, 0.0], "altitude": 1.0, "speed": 0.2},
                                                     {"hold": 5.0, "standoff": 1.5},
                                                     {"goto": [10.0, 0.0, 4.0], "speed": 0.2}]}, "m")
    first, second, third = (seg.t0 + 0.5 * seg.duration for seg in mission.segments)
    assert mission.terrain(first) == ("altitude", 1.0) and mission.terrain(second) == ("standoff", 1.5)
    assert mission.terrain(third) is None and mission.follows_terrain
    assert mission.segments[0].p1[2] == 5.0                       # planned at the depth it started at
    with pytest.raises(ConfigError, match="path\\[0\\]: an altitude or standoff leg takes its depth"):
        mission.check_offline()


@pytest.mark.parametrize("entry, words", [
    ({"goto": [10.0, 0.0], "speed": 0.2}, "or [north, east] with an altitude"),
    ({"goto": [10.0, 0.0], "altitude": 0.2, "speed": 0.2}, "greater than or equal to 0.3"),
    ({"goto": [10.0, 0.0], "altitude": 1.0, "standoff": 1.0, "speed": 0.2}, "not both"),
    ({"line": [0.2, 0.0, 0.0], "duration": 5.0, "altitude": 1.0}, "apply to goto and hold, not line"),
])
def test_bad_terrain_legs_are_refused_in_one_line(entry, words):
    with pytest.raises(ConfigError) as error:
        mission_from_dict({**MISSION, "path": [entry]}, "m.yaml")
    assert words in str(error.value) and "\n" not in str(error.value)


def _distance_sensor(component: int, cm: int, quality: int, orientation: int = 25):
    from pymavlink.dialects.v20 import ardupilotmega as mavlink

    msg = mavlink.MAVLink_distance_sensor_message(0, 20, 12000, cm, 1, 0, orientation, 0, 0.0, 0.0, [0.0] * 4,
                                                  quality)
    msg._header = mavlink.MAVLink_header(msg.id, srcSystem=1, srcComponent=component)
    return msg


def test_the_run_reads_the_sounders_own_readings_over_the_autopilots_copy():
    from rov_mav.flight.state.soundings import Soundings

    soundings = Soundings()
    soundings.update(_distance_sensor(1, 200, 0), 0.0)            # the autopilot's copy, before the sounder is heard
    soundings.update(_distance_sensor(194, 201, 100), 0.1)
    soundings.update(_distance_sensor(1, 200, 100), 0.2)          # its slower copy, once the sounder's own is heard
    soundings.update(_distance_sensor(194, 150, 1), 0.3)          # "invalid"
    soundings.update(_distance_sensor(194, 150, 100, orientation=0), 0.4)   # looking forward: not a height
    taken = soundings.take()
    assert [(s.t, s.distance, s.quality) for s in taken] == [(0.0, 2.0, 100), (0.1, 2.01, 100), (0.3, 1.5, 0)]
    assert soundings.take() == []


def test_a_point_goes_to_latitude_and_longitude_and_back_on_the_same_flat_earth():
    from rov_mav.units import lat_lon, north_east

    origin = (47.6, -122.3, 0.0)
    lat, lon = lat_lon(37.5, -12.25, origin)
    assert north_east(lat, lon, origin) == pytest.approx((37.5, -12.25), abs=1e-9)
