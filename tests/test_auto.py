"""ArduSub's AUTO on the built-in vehicle's autopilot (`sim_bridge.modes.auto`, `sim_bridge.modes.wpnav`): the
straight leg's geometry and reach, the mission's sequence and texts, the terrain-frame waypoints held above a slope
from the rangefinder, and the terrain failsafe; on the autopilot, thrusters and plant in process (no sockets)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from auto_helpers import RELATIVE, TERRAIN, Dive, item

from rov_mav.model.seafloor import Surface
from sim_bridge.autopilot.ardusub import MODES, ArduSub
from sim_bridge.autopilot.params import Params
from sim_bridge.gcs import telemetry
from sim_bridge.modes.wpnav import Limits, WaypointNav, kinematic_limit, stopping_distance, stopping_point

LIMITS = Limits(speed=1.0, speed_up=2.5, speed_down=1.5, accel=2.5, accel_z=1.0, radius=2.0, p=1.0)
SLOPE = Surface(depth=8.0, slope=0.1)            # rising 10 % toward the north


def test_kinematic_limit_and_stopping_distance_as_ap_math_has_them():
    assert kinematic_limit(np.array([3.0, 4.0, 0.0]), 1.0, 2.5, 1.5) == pytest.approx(1.0)
    assert kinematic_limit(np.array([0.0, 0.0, -2.0]), 1.0, 2.5, 1.5) == pytest.approx(1.5)      # down
    assert kinematic_limit(np.array([1.0, 0.0, 1.0]), 1.0, 0.5, 1.5) == pytest.approx(0.5 * math.sqrt(2))
    assert stopping_distance(0.5, 1.0, 2.5) == pytest.approx(0.5)                      # linear below accel / p
    assert stopping_distance(-4.0, 1.0, 2.5) == pytest.approx(-(1.25 + 16 / 5))
    point = stopping_point(np.array([1.0, 2.0, 3.0, 0, 0, 0]), np.array([0.5, 0.0, 0.0]),
                           {"WPNAV_SPEED": 100.0, "PSC_POSXY_P": 1.0, "WPNAV_ACCEL": 250.0, "PSC_POSZ_P": 3.0,
                            "WPNAV_ACCEL_Z": 100.0})
    assert point == pytest.approx([1.5, 2.0, -3.0])                                     # (north, east, up)


def test_a_leg_moves_its_target_at_the_speed_and_is_reached_within_the_radius():
    """The target accelerates at WPNAV_ACCEL to WPNAV_SPEED along the line and brakes to stop on the destination;
    it is reached once the target arrived with the vehicle within WPNAV_RADIUS, not before."""
    nav = WaypointNav()
    nav.init(np.zeros(3), 0.0)
    assert nav.reached and nav.set_destination((10.0, 0.0, -2.0), False, None, np.zeros(3), 0.0)
    assert not nav.reached and nav.origin == pytest.approx([0, 0, 0])
    t, speeds, here = 0.0, [], np.zeros(3)
    while not nav.reached and t < 30:
        target, velocity = nav.advance(here, np.zeros(3) if t == 0 else velocity, None, LIMITS, t, 0.01)
        here = target.copy()                              # a vehicle on the target
        speeds.append(float(np.linalg.norm(velocity)))
        t += 0.01
    speed = kinematic_limit(np.array([10.0, 0.0, -2.0]), 1.0, 2.5, 1.5)
    assert max(speeds) == pytest.approx(speed, rel=1e-3)
    assert 10.2 / speed < t < 10.2 / speed + 1.5 and here == pytest.approx([10, 0, -2])
    assert nav.bearing() == pytest.approx(0.0)
    aside = WaypointNav()                                 # a vehicle keeping pace 2.5 m to the side
    aside.init(np.zeros(3), 0.0)
    aside.set_destination((4.0, 3.0, 0.0), False, None, np.zeros(3), 0.0)
    side, velocity = np.array([-0.6, 0.8, 0.0]) * 2.5, np.zeros(3)
    for k in range(2000):
        target, velocity = aside.advance(aside.origin + side if k == 0 else target + side, velocity, None, LIMITS,
                                         k * 0.01, 0.01)
    assert aside.travelled == pytest.approx(5.0) and not aside.reached
    aside.advance(target + side * 0.7, np.zeros(3), None, LIMITS, 20.0, 0.01)
    assert aside.reached and aside.bearing() == pytest.approx(math.atan2(3, 4))
    stuck = WaypointNav()                                 # the track scalar: a target waits for a stuck vehicle
    stuck.init(np.zeros(3), 0.0)
    stuck.set_destination((10.0, 0.0, 0.0), False, None, np.zeros(3), 0.0)
    for k in range(4000):
        stuck.advance(np.zeros(3), np.zeros(3), None, LIMITS, k * 0.01, 0.01)
        if k == 1999:
            waited = stuck.travelled
    assert waited < 3.0 and stuck.travelled - waited < 0.1


def test_a_terrain_leg_converts_its_origin_needs_terrain_data_to_start_and_does_not_advance_without_it():
    """`set_wp_destination_NEU_m`: from a depth leg to a terrain leg the origin becomes a height (up + the bottom's
    depth) and needs a terrain offset; terrain after terrain needs none; `advance_wp_target_along_track` holds the
    target and reports the failure without one."""
    nav = WaypointNav()
    nav.init(np.array([0.0, 0.0, -5.0]), 0.0)                          # 5 m deep
    assert not nav.set_destination((6.0, 0.0, 1.0), True, None, np.zeros(3), 0.0)
    assert not nav.terrain and nav.reached                              # nothing changed
    assert nav.set_destination((6.0, 0.0, 1.0), True, 8.0, np.zeros(3), 0.0)
    assert nav.terrain and nav.origin == pytest.approx([0, 0, 3.0])     # 3 m above a bottom 8 m deep
    assert nav.advance(np.array([0, 0, -5.0]), np.zeros(3), None, LIMITS, 0.01, 0.01) is None
    assert nav.travelled == 0.0
    target, _ = nav.advance(np.array([0, 0, -5.0]), np.zeros(3), 8.0, LIMITS, 0.02, 0.01)
    assert target[2] == pytest.approx(3.0, abs=0.01)
    nav.reached = True
    assert nav.set_destination((9.0, 0.0, 1.0), True, None, np.zeros(3), 0.03)   # terrain after terrain
    assert nav.origin == pytest.approx([6, 0, 1])


def test_auto_needs_a_position_and_a_mission_not_arming():
    """`Sub::set_mode`: position first ("requires position"), then `ModeAuto::init` (a mission past home)."""
    items = []
    sub = ArduSub(Params(), mission=lambda: items)
    assert not sub.set_mode(MODES["AUTO"]) and sub.texts[-1][1] == "Flight mode change failed AUTO"
    items[:] = [item(0, 0, 0.0, RELATIVE), item(5, 0, -2.0, RELATIVE)]
    sub.position_ok_flags = (False, False)
    assert not sub.set_mode(MODES["AUTO"]) and sub.texts[-1][1] == "Mode change failed: AUTO requires position"
    sub.position_ok_flags = (True, True)
    sub.texts.clear()
    assert sub.set_mode(MODES["AUTO"]) and not sub.armed and sub.base_mode() & 8
    assert sub.texts == [(6, "Mission: 1 WP")]


def test_items_it_cannot_start_are_passed_over_with_ardusubs_texts():
    """`Sub::start_command`'s altitude-frame checks and its default case; the mission goes on to the next item."""
    dive = Dive(SLOPE, 6.0, [item(3, 0, 1.0, RELATIVE), item(3, 0, -1.0, TERRAIN), item(3, 0, 0.0, 0),
                             item(3, 0, -4.0, RELATIVE, command=19), item(2, 0, -5.0, RELATIVE)])
    dive.fly(0.5)
    assert dive.sub.set_mode(MODES["AUTO"])
    assert dive.texts() == ["Mission: 1 WP", "Alt above home must be negative", "Mission: 2 WP",
                            "Alt above terrain must be positive", "Mission: 3 WP", "Bad alt frame",
                            "Mission: 4 LoitTime", "Ignoring command 19", "Mission: 5 WP"]
    assert dive.sub.auto.mission_current(len(dive.items)) == (5, telemetry.mavlink.MISSION_STATE_ACTIVE)


def test_terrain_waypoints_are_flown_a_metre_above_a_slope_and_the_end_holds_the_stopping_point():
    """PR #26450's terrain frame: the legs straight in height above the bottom (the rangefinder's), each waypoint
    reached ("Reached command #N", MISSION_ITEM_REACHED's queue), its hold kept; at the end the mission is complete
    and the vehicle holds where it stopped, at its depth, still armed in AUTO (`exit_mission`)."""
    dive = Dive(SLOPE, 6.0, [item(3, 0, 1.0), item(10, 0, 1.0), item(15, 4, 1.0, hold=2)])
    dive.fly(1.0)
    dive.sub.arm(True)
    assert dive.sub.set_mode(MODES["AUTO"])
    samples, reached_at = [], {}
    while dive.t < 60 and dive.sub.auto.state != "complete":
        samples += dive.fly(0.5)
        for seq in dive.sub.auto.reached:
            reached_at.setdefault(seq, dive.t)
    assert list(reached_at) == [1, 2, 3] and dive.sub.auto.reached == [1, 2, 3]
    texts = dive.texts()
    assert [t for t in texts if t.startswith(("Mission", "Reached"))] == [
        "Mission: 1 WP", "Reached command #1", "Mission: 2 WP", "Reached command #2", "Mission: 3 WP",
        "Reached command #3"]
    legs = np.array([h for t, _, h in samples if t > reached_at[1]])
    print(f"legs 2-3: height {legs.mean():.3f} m mean, {np.sqrt(np.mean((legs - 1) ** 2)) * 100:.1f} cm RMS")
    assert np.sqrt(np.mean((legs - 1.0) ** 2)) < 0.1 and np.abs(legs - 1.0).max() < 0.25
    end = samples[-1][1]
    assert np.hypot(end[0] - 15, end[1] - 4) < 2.0                       # within WP_RADIUS_M of the last
    held = dive.fly(10.0)
    assert dive.sub.armed and dive.sub.mode == MODES["AUTO"]
    assert dive.sub.auto.mission_current(len(dive.items)) == (3, telemetry.mavlink.MISSION_STATE_COMPLETE)
    assert np.ptp([e[2] for _, e, _ in held[20:]]) < 0.1                 # the depth held, not the height
    assert max(np.hypot(e[0] - held[-1][1][0], e[1] - held[-1][1][1]) for _, e, _ in held[40:]) < 0.5


def test_disarmed_in_auto_the_mission_steps_through_as_ardusubs_does():
    """`auto_wp_run` disarmed restarts the navigator (`wp_and_spline_init`), which counts its destination reached:
    each waypoint passes after its hold, and the vehicle never moves."""
    dive = Dive(SLOPE, 6.0, [item(5, 0, -6.0, RELATIVE, hold=1), item(9, 0, -6.0, RELATIVE)])
    dive.fly(0.5)
    assert dive.sub.set_mode(MODES["AUTO"])
    dive.fly(2.0)
    assert dive.sub.auto.reached == [1, 2] and dive.sub.auto.state == "complete"
    assert np.linalg.norm(dive.plant.eta[:2]) < 0.01


def test_a_terrain_waypoint_without_a_rangefinder_disarms_and_a_depth_one_flies():
    """`auto_wp_start`: no terrain offset for the first terrain leg -> "Terrain data (rangefinder) not available" and
    `failsafe_terrain_on_event`: no rangefinder, so the action, FS_TERRAIN_ENAB 0: disarm. Depth legs need none."""
    dive = Dive(SLOPE, 6.0, [item(4, 0, 1.0)], RNGFND1_TYPE=0)
    dive.fly(0.5)
    dive.sub.arm(True)
    assert dive.sub.set_mode(MODES["AUTO"]) and not dive.sub.armed
    assert dive.texts() == ["Mission: 1 WP", "Terrain data (rangefinder) not available"]
    depth = Dive(SLOPE, 6.0, [item(4, 0, -5.0, RELATIVE)], RNGFND1_TYPE=0)
    depth.fly(0.5)
    depth.sub.arm(True)
    assert depth.sub.set_mode(MODES["AUTO"])
    depth.fly(20.0)
    assert depth.sub.auto.reached == [1] and np.linalg.norm(depth.plant.eta[:3] - [4, 0, 5]) < 1.0


@pytest.mark.parametrize("action,after", [(0, "disarmed"), (1, MODES["POSHOLD"])])
def test_a_silent_sounder_on_a_terrain_leg_triggers_the_terrain_failsafe(action, after):
    """The sounder silent: the rangefinder unhealthy, the target held; 1 s of it "Failsafe terrain triggered"; no
    data, so no recovery: FS_TERRAIN_ENAB's action (0 disarm, 1 POSHOLD)."""
    dive = Dive(SLOPE, 7.0, [item(12, 0, 1.0)], FS_TERRAIN_ENAB=action)
    dive.fly(1.0)
    dive.sub.arm(True)
    assert dive.sub.set_mode(MODES["AUTO"])
    dive.fly(4.0)
    dive.silent = (dive.t, dive.t + 10.0)
    start = dive.t
    dive.fly(1.4)
    assert dive.sub.armed and "Failsafe terrain triggered" not in dive.texts()
    dive.fly(1.0)
    texts = dive.texts()
    assert "Failsafe terrain triggered" in texts and dive.t - start < 2.5
    if after == "disarmed":            # and, disarmed in AUTO, its waypoint passes (see the test above)
        assert not dive.sub.armed and texts[texts.index("Failsafe terrain triggered") + 1:] == ["Reached command #1"]
    else:
        assert dive.sub.mode == after and dive.sub.armed and texts[-1] == "Failsafe terrain triggered"


def test_a_bad_signal_on_a_terrain_leg_is_recovered_and_the_mission_resumes():
    """Readings under RNGFND_SQ_MIN (status Good, not healthy): the failsafe's recovery holds the depth ("Attempting
    auto failsafe recovery"); 1.5 s healthy again, "Terrain failsafe recovery successful!" and the waypoint starts
    again from where the vehicle is, and is reached."""
    dive = Dive(SLOPE, 7.0, [item(10, 0, 1.0)])
    dive.fly(1.0)
    dive.sub.arm(True)
    assert dive.sub.set_mode(MODES["AUTO"])
    dive.fly(4.0)
    bad = (dive.t, dive.t + 4.0)
    dive.quality = lambda t, q: 50 if bad[0] <= t < bad[1] else q
    dive.fly(2.5)
    assert dive.texts()[-2:] == ["Failsafe terrain triggered", "Attempting auto failsafe recovery"]
    depth = dive.plant.eta[2]
    dive.fly(1.0)
    assert abs(dive.plant.eta[2] - depth) < 0.1 and dive.sub.auto.state == "stopped"
    dive.fly(6.0)
    assert dive.texts()[-2:] == ["Terrain failsafe recovery successful!", "Mission: 1 WP"]
    assert dive.sub.armed and not dive.sub.failsafes.terrain
    dive.fly(20.0)
    assert dive.sub.auto.reached == [1] and abs(dive.height() - 1.0) < 0.2


def test_leaving_auto_stops_the_mission_and_coming_back_resumes_its_waypoint():
    """`Sub::exit_mode` stops the mission; MIS_RESTART 0 resumes: the running waypoint starts again."""
    dive = Dive(SLOPE, 6.0, [item(4, 0, -6.0, RELATIVE), item(8, 0, -6.0, RELATIVE)])
    dive.fly(0.5)
    dive.sub.arm(True)
    assert dive.sub.set_mode(MODES["AUTO"])
    dive.fly(12.0)
    assert dive.sub.auto.reached == [1] and dive.sub.auto.index == 2
    assert dive.sub.set_mode(MODES["POSHOLD"]) and dive.sub.auto.state == "stopped"
    assert dive.sub.auto.mission_current(len(dive.items)) == (2, telemetry.mavlink.MISSION_STATE_NOT_STARTED)
    dive.sub.texts.clear()
    assert dive.sub.set_mode(MODES["AUTO"]) and dive.texts() == ["Mission: 2 WP"]
