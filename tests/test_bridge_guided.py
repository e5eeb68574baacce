"""ArduSub's GUIDED mode on the bridge's vehicle (logic, mixer, T200, plant; no sockets): SET_POSITION_TARGET_LOCAL_NED
targets flown by the position controller (position P -> velocity PID -> the mixer), measured on the plant's true
state."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rov_mav.model.environment import Environment
from rov_mav.model.plant import Plant
from rov_mav.model.thrusters import load_t200
from rov_mav.model.vehicle import load_vehicle
from sim_bridge.autopilot.ardusub import MODES, ArduSub
from sim_bridge.hardware.battery import Battery
from sim_bridge.modes.guided import FRAME_BODY_NED, FRAME_LOCAL_NED, sqrt_controller
from rov_mav.units import EARTH_RADIUS
from sim_bridge.autopilot.params import Params
from sim_bridge.hardware.physics import Physics

STEP = 0.0025
POS_VEL_YAW = 0x9C0          # acceleration and yaw rate ignored
POS_YAW = 0x9F8              # velocity too
VEL_YAW = 0x9C7              # position ignored


class Dive:
    """The emulated ArduSub armed in GUIDED on the bridge's physics, from (0, 0, 2 m), heading north."""

    def __init__(self, disturbance=(0, 0, 0, 0, 0, 0), firmware: str = "4.7"):
        vehicle = load_vehicle()
        self.plant = Plant(vehicle, Environment(disturbance=np.array(disturbance, dtype=float)),
                           eta0=np.array([0, 0, 2.0, 0, 0, 0.0]))
        self.physics = Physics(vehicle, self.plant, Battery(), load_t200(), STEP)
        params = Params(firmware)
        params.set("FS_PILOT_INPUT", 0)
        params.set("FS_GCS_ENABLE", 0)
        self.sub = ArduSub(params)
        assert self.sub.set_mode(MODES["GUIDED"])
        self.sub.arm(True)
        self.t = 0.0

    def target(self, frame=FRAME_LOCAL_NED, mask=POS_VEL_YAW, pos=(0, 0, 0), vel=(0, 0, 0), yaw=0.0,
               acc=(0, 0, 0)) -> bool:
        return self.sub.position_target(frame, mask, pos, vel, yaw, self.t, acc)

    def fly(self, seconds: float, each=None) -> list[np.ndarray]:
        """Step for `seconds`; `each(t)` (if given) is called every 0.1 s first; the true eta every 0.1 s."""
        poses = []
        for k in range(int(round(seconds / STEP))):
            if k % 40 == 0:
                if each is not None:
                    each(self.t)
                poses.append(np.array(self.plant.eta))
            self.sub.update(self.t, (np.array(self.plant.eta), np.array(self.plant.nu)))
            self.physics.step(self.sub.servo_outputs()[:8])
            self.t += STEP
        return poses


def test_sqrt_controller_is_linear_near_and_square_root_far():
    assert sqrt_controller(10.0, 1.0, 250.0, 0.0) == pytest.approx(10.0)
    assert sqrt_controller(1000.0, 1.0, 250.0, 0.0) == pytest.approx(math.sqrt(2 * 250 * (1000 - 125)))
    assert sqrt_controller(-1000.0, 1.0, 250.0, 0.0) < 0


def test_converges_to_a_setpoint_and_holds_it_against_a_current():
    dive = Dive(disturbance=(3.0, -3.0, 2.0, 0, 0, 0))
    dive.sub.update(0.0, (np.array(dive.plant.eta), np.array(dive.plant.nu)))
    assert dive.target(pos=(2.0, -1.0, 2.5), yaw=math.radians(45))
    dive.fly(40.0)
    eta = dive.plant.eta
    assert np.linalg.norm(eta[:3] - [2.0, -1.0, 2.5]) < 0.05
    assert abs(math.remainder(eta[5] - math.radians(45), 2 * math.pi)) < math.radians(2)
    assert abs(eta[3]) < math.radians(3) and abs(eta[4]) < math.radians(3)


def test_follows_a_moving_setpoint_with_velocity_feed_forward():
    """A 0.2 m/s line streamed at 10 Hz: with the velocity given, the lag is far smaller than without."""
    def lag(mask: int) -> float:
        dive = Dive()
        dive.fly(1.0)

        def send(t):
            dive.target(mask=mask, pos=(0.2 * (t - 1.0), 0, 2.0), vel=(0.2, 0, 0))
        poses = dive.fly(30.0, send)
        errors = [abs(0.2 * 0.1 * k - p[0]) for k, p in enumerate(poses)][150:]
        return float(np.mean(errors))

    with_ff, without = lag(POS_VEL_YAW), lag(POS_YAW)
    assert with_ff < 0.06 and without > 4 * with_ff


def test_velocity_only_holds_no_horizontal_position_but_the_depth_and_the_timeout_stops_it():
    """Guided_Velocity (mode_guided.cpp): the horizontal position target follows the vehicle every loop
    (`NE_stop_pos_stabilisation`), so a current that pushes it north is not undone, where a position target's is; the
    depth target is the climb rate integrated (held at 0); 3 s after the last target the velocity is zeroed and the
    vehicle stays armed in GUIDED wherever it got to."""
    current = (10.0, 0, 0, 0, 0, 0)                            # N along the body x (north: heading 0)
    dive = Dive(disturbance=current)
    dive.fly(1.0)
    assert dive.target(mask=VEL_YAW, vel=(0.0, 0.3, 0.0), pos=(50, 50, 50))   # position fields masked out
    dive.fly(2.0)
    moving = dive.plant.eta[1]
    dive.fly(20.0)
    eta = dive.plant.eta
    assert 0.25 < moving and 0.6 < eta[1] < 1.2, eta             # about 3 s at 0.3 m/s east, then stopped
    assert eta[0] > 0.5 and abs(eta[2] - 2.0) < 0.05, eta        # pushed north and left there; depth held
    assert dive.sub.armed and dive.sub.mode == MODES["GUIDED"]
    held = Dive(disturbance=current)
    held.fly(1.0)
    assert held.target(mask=POS_YAW, pos=(0.0, 0.9, 2.0))
    held.fly(22.0)
    assert np.linalg.norm(held.plant.eta[:3] - [0.0, 0.9, 2.0]) < 0.1, held.plant.eta


def test_yaw_rate_alone_turns_at_it_and_with_a_heading_caps_the_turn():
    """guided_set_yaw_state: a yaw rate without a heading turns the vehicle at that rate; a heading with a rate is
    turned to at min(rate, 60 deg/s); BODY_FRD is a body frame, rotated by the heading."""
    dive = Dive()
    dive.fly(1.0)
    rate_only = 0x5C7                                          # velocity, yaw rate (position, acceleration, yaw off)
    assert dive.sub.position_target(FRAME_LOCAL_NED, rate_only, (0, 0, 0), (0, 0, 0), 0.0, dive.t, (0, 0, 0),
                                    math.radians(10))
    dive.fly(2.0)                                              # no timeout: a rate is the heading's, not a velocity
    first = dive.plant.eta[5]
    dive.fly(2.0)
    assert math.degrees(dive.plant.eta[5] - first) == pytest.approx(20.0, abs=3.0)
    slow = Dive()
    slow.fly(1.0)
    heading_and_rate = 0x1F8                                   # position, yaw, yaw rate
    assert slow.sub.position_target(FRAME_LOCAL_NED, heading_and_rate, (0, 0, 2.0), (0, 0, 0), math.radians(90),
                                    slow.t, (0, 0, 0), math.radians(15))
    turns = slow.fly(4.0)
    assert 40 < math.degrees(turns[-1][5]) < 70                 # 15 deg/s for 4 s, not 60 deg/s (there in 1.5 s)
    frd = Dive()
    frd.fly(1.0)
    assert frd.sub.position_target(12, POS_YAW, (0, 1.0, 0), (0, 0, 0), 0.0, frd.t)   # MAV_FRAME_BODY_FRD
    frd.fly(30.0)
    assert np.linalg.norm(frd.plant.eta[:3] - [0, 1.0, 2.0]) < 0.05


def test_masked_position_fields_are_ignored_and_unsupported_targets_too():
    dive = Dive()
    dive.fly(1.0)
    assert not dive.target(frame=6, pos=(5, 5, 5))              # MAV_FRAME_GLOBAL_RELATIVE_ALT_INT: ignored
    assert not dive.target(mask=0x9FF, pos=(5, 5, 5))           # nothing usable
    assert not dive.target(mask=0x838, pos=(5, 5, 5))           # acceleration without velocity: ignored (4.7.2)
    dive.fly(10.0)
    assert np.linalg.norm(dive.plant.eta[:3] - [0, 0, 2.0]) < 0.05
    assert dive.target(frame=FRAME_BODY_NED, mask=POS_YAW, pos=(0, 1.0, 0), yaw=0.0)   # 1 m to the right
    dive.fly(40.0)
    assert np.linalg.norm(dive.plant.eta[:3] - [0, 1.0, 2.0]) < 0.05


def test_acceleration_is_taken_with_position_and_velocity_on_4_7_and_never_on_4_5():
    """4.7.2's Guided_PosVelAccel: position + velocity + acceleration accepted, the acceleration fed forward (a
    swaying path is followed a little closer with it: Sub turns an acceleration into a lean angle's share of
    ANGLE_MAX, so 0.24 m/s/s is about 3 % of an axis); 4.5 drops any target whose acceleration is not ignored."""
    assert not Dive(firmware="4.5").target(mask=0x800, pos=(1, 0, 2))

    def error(mask: int) -> float:
        dive = Dive()
        dive.fly(1.0)

        def send(t):
            w, t = 0.4, t - 1.0
            assert dive.target(mask=mask, pos=(1.5 * math.sin(w * t), 0, 2.0), vel=(1.5 * w * math.cos(w * t), 0, 0),
                               acc=(-1.5 * w * w * math.sin(w * t), 0, 0))
        poses = dive.fly(40.0, send)
        return float(np.mean([abs(1.5 * math.sin(0.4 * 0.1 * k) - p[0]) for k, p in enumerate(poses)][100:]))

    with_acc, without = error(0x800), error(POS_VEL_YAW)
    assert with_acc < 0.99 * without, (with_acc, without)              # measured: 0.377 m against 0.384


def test_targets_outside_guided_and_disarmed_do_nothing():
    dive = Dive()
    dive.sub.arm(False)
    dive.target(pos=(3, 0, 2))
    dive.fly(3.0)
    assert np.all(dive.sub.servo_outputs()[:8] == 1500) and abs(dive.plant.eta[0]) < 0.05
    dive.sub.set_mode(MODES["MANUAL"])
    assert not dive.target(pos=(3, 0, 2))


ORIGIN = (47.6, -122.3, 10.0)         # lat, lon deg, alt m above the sea


def _global(dive: Dive, frame: int, north: float, east: float, alt: float, mask: int = POS_YAW,
            vel=(0.0, 0.0, 0.0)) -> bool:
    lat = ORIGIN[0] + math.degrees(north / EARTH_RADIUS)
    lon = ORIGIN[1] + math.degrees(east / (EARTH_RADIUS * math.cos(math.radians(ORIGIN[0]))))
    return dive.sub.position_target_global(frame, mask, lat, lon, alt, vel, dive.t)


def test_global_int_targets_by_their_altitude_frame_and_in_alt_hold_the_depth():
    """SET_POSITION_TARGET_GLOBAL_INT (GCS_MAVLINK_Sub::handle_message): in GUIDED a position from the EKF origin,
    its altitude above home (RELATIVE_ALT; home is the origin here) or above the sea (GLOBAL); above the terrain
    a position alone is dropped (PR #27767 takes position and velocity only); in ALT_HOLD the altitude (above the
    origin) is the depth target; in MANUAL it is ignored."""
    dive = Dive()
    dive.sub.origin = ORIGIN
    dive.fly(1.0)
    assert _global(dive, 6, 2.0, 1.0, -3.0)                           # GLOBAL_RELATIVE_ALT_INT
    dive.fly(40.0)
    assert np.linalg.norm(dive.plant.eta[:3] - [2.0, 1.0, 3.0]) < 0.05, dive.plant.eta
    assert _global(dive, 5, 0.0, 0.0, ORIGIN[2] - 2.0)                # GLOBAL_INT: 2 m below the origin's altitude
    assert not _global(dive, 11, 5.0, 5.0, 1.0)                        # GLOBAL_TERRAIN_ALT_INT, a position alone
    dive.fly(40.0)
    assert np.linalg.norm(dive.plant.eta[:3] - [0.0, 0.0, 2.0]) < 0.1, dive.plant.eta
    assert dive.sub.set_mode(MODES["ALT_HOLD"])
    assert _global(dive, 6, 50.0, 50.0, -4.0)                          # the depth only, lat/lon not used
    dive.fly(30.0)
    assert abs(dive.plant.eta[2] - 4.0) < 0.1 and np.linalg.norm(dive.plant.eta[:2]) < 0.3, dive.plant.eta
    assert dive.sub.set_mode(MODES["MANUAL"])
    assert not _global(dive, 6, 1.0, 1.0, -1.0)


def test_a_terrain_target_holds_its_range_up_a_slope_and_needs_a_rangefinder_to_start():
    """PR #27767's GUIDED ABOVE_TERRAIN (the live log's ArduSub; 4.7.2 drops such a target underwater): position and
    velocity in GLOBAL_TERRAIN_ALT_INT, the altitude the rangefinder range to hold. Refused with "Terrain data
    (rangefinder) not available" before the rangefinder is healthy; then a line at 0.2 m/s up a 10 % slope keeps
    the range, and while the sounder is silent the depth is held."""
    from rov_mav.model.seafloor import Surface
    from sim_bridge.navigation.echo_sounder import EchoSounder

    floor = Surface(depth=4.0, slope=0.1)
    dive = Dive()
    dive.sub.params.set("RNGFND1_TYPE", 10)
    dive.sub.rangefinder.__init__(dive.sub.params)                    # set up at boot, as ArduSub reads it
    dive.sub.origin = ORIGIN
    sounder = EchoSounder("ideal", 0, floor, None)
    silent = [math.inf, -math.inf]
    assert not _global(dive, 11, 0.0, 0.0, 2.0, mask=POS_VEL_YAW, vel=(0.2, 0.0, 0.0))
    assert dive.sub.texts[-1][1] == "Terrain data (rangefinder) not available"

    def each(t):
        for reading in sounder.sample(t, dive.plant.eta, dive.plant.nu):
            if not silent[0] <= t < silent[1]:
                for msg, _ in sounder.messages(reading, int(t * 1000)):
                    dive.sub.rangefinder.handle(msg.orientation, msg.current_distance, msg.min_distance,
                                                msg.max_distance, msg.signal_quality, msg.type, t)
        north = 0.2 * max(t - 3.0, 0.0)
        if t >= 3.0:
            assert _global(dive, 11, north, 0.0, 2.0, mask=POS_VEL_YAW, vel=(0.2, 0.0, 0.0))

    poses = dive.fly(40.0, each)
    heights = np.array([floor.depth_at(p[0], p[1]) - p[2] for p in poses[200:]])
    assert poses[-1][0] > 5.0 and np.sqrt(np.mean((heights - 2.0) ** 2)) < 0.1, heights
    silent[:] = [dive.t, dive.t + 3.0]
    held = dive.fly(3.0, each)
    assert max(p[2] for p in held) <= held[0][2] + 0.03                 # no move toward the bottom
