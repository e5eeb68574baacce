"""ArduSub's rangefinder and SURFTRAK on the built-in vehicle's autopilot (`sim_bridge.modes.terrain`), driven as
its main loop drives them: the backend's status and health, and the range held over a bottom that moves."""

from __future__ import annotations

import numpy as np
import pytest

from rov_mav.model.environment import Environment
from rov_mav.model.plant import Plant
from rov_mav.model.seafloor import Surface
from rov_mav.model.thrusters import load_t200
from rov_mav.model.vehicle import load_vehicle
from sim_bridge.autopilot.ardusub import MODES, ArduSub
from sim_bridge.autopilot.params import Params
from sim_bridge.modes.terrain import GOOD, NO_DATA, OUT_OF_RANGE_HIGH, Rangefinder
from sim_bridge.hardware.battery import Battery
from sim_bridge.hardware.physics import Physics
from sim_bridge.navigation.echo_sounder import EchoSounder

STEP = 0.0025
NEUTRAL = [1500] * 8
FORWARD = [1500, 1500, 1500, 1500, 1600, 1500, 1500, 1500]
DOWN_STICK = [1500, 1500, 1300, 1500, 1500, 1500, 1500, 1500]


def rangefinder(**values) -> tuple[Rangefinder, Params]:
    params = Params()
    for name, value in {"RNGFND1_TYPE": 10, **values}.items():
        params.set(name, value)
    return Rangefinder(params), params


def feed(rf: Rangefinder, params, seconds: float, distance_cm: int, quality: int = 100, start: float = 0.0,
         orientation: int = 25) -> float:
    """Readings every 0.1 s and the 20 Hz update between them, from `start`; the time reached."""
    t = start
    while t < start + seconds - 1e-9:
        if round(t * 100) % 10 == 0:
            rf.handle(orientation, distance_cm, 20, 12000, quality, 1, t)
        rf.update(t, 5.0, params)
        t += 0.05
    return t


def test_the_backend_takes_its_orientation_maps_quality_and_counts_three_good_updates():
    rf, params = rangefinder()
    rf.handle(24, 150, 20, 12000, 100, 1, 0.0)           # looking up: not this rangefinder's
    rf.update(0.0, 5.0, params)
    assert rf.status == NO_DATA
    feed(rf, params, 0.1, 150)
    assert rf.status == GOOD and not rf.healthy           # two good updates so far
    t = feed(rf, params, 0.1, 150, start=0.1)
    assert rf.healthy and rf.alt_ok(t) and rf.terrain_depth == pytest.approx(6.5)
    rf.handle(25, 150, 20, 12000, 0, 1, t)
    assert rf.quality == -1                                # 0, "unknown": passes the gate
    rf.handle(25, 150, 20, 12000, 1, 1, t)
    assert rf.quality == 0                                 # 1, "invalid"


def test_quality_under_rngfnd_sq_min_or_a_range_beyond_max_is_not_healthy_and_silence_is_no_data():
    rf, params = rangefinder()
    t = feed(rf, params, 1.0, 150, quality=89)
    assert rf.status == GOOD and not rf.healthy
    t = feed(rf, params, 1.0, 800, start=t)               # RNGFND1_MAX 7 m
    assert rf.status == OUT_OF_RANGE_HIGH and not rf.healthy
    rf.update(t + 0.6, 5.0, params)                       # 500 ms without a message
    assert rf.status == NO_DATA and rf.reading() is None


def test_the_range_is_low_passed_and_restarts_after_a_second_without_health():
    rf, params = rangefinder()
    t = feed(rf, params, 5.0, 200)
    t = feed(rf, params, 1.0, 300, start=t)
    assert 2.0 < rf.filtered < 2.9                        # 0.25 Hz: a second moves it part of the way
    t = feed(rf, params, 1.5, 300, quality=50, start=t)   # unhealthy for 1.5 s
    feed(rf, params, 0.25, 400, start=t)
    assert rf.filtered == pytest.approx(4.0)              # restarted from the reading, not filtered toward it


class Dive:
    """The autopilot, its thrusters and the plant over `floor`, with a sounder's readings handed to the autopilot as
    its router does; stick channels held by a GCS override."""

    def __init__(self, floor: Surface, depth: float, sounder="ideal"):
        vehicle = load_vehicle()
        self.floor = floor
        self.plant = Plant(vehicle, Environment(), eta0=np.array([0, 0, depth, 0, 0, 0.0]))
        self.physics = Physics(vehicle, self.plant, Battery(), load_t200(), STEP)
        params = Params()
        for name, value in {"FS_PILOT_INPUT": 0, "FS_GCS_ENABLE": 0, "RNGFND1_TYPE": 10}.items():
            params.set(name, value)
        self.sub = ArduSub(params)
        self.sounder = EchoSounder(sounder, 0, floor, None)
        self.t = 0.0
        self.silent_until = -1.0
        self.sticks = NEUTRAL

    def fly(self, seconds: float, every: float = 0.5) -> list[tuple[float, float, float, float | None]]:
        """(t, true height, depth, depth target) every `every` s."""
        out = []
        for k in range(round(seconds / STEP)):
            t = self.t
            for reading in self.sounder.sample(t, self.plant.eta, self.plant.nu):
                if t >= self.silent_until:
                    for msg, _ in self.sounder.messages(reading, int(t * 1000)):
                        self.sub.rangefinder.handle(msg.orientation, msg.current_distance, msg.min_distance,
                                                    msg.max_distance, msg.signal_quality, msg.type, t)
            if k % 40 == 0:
                self.sub.rc_override(255, self.sticks + [0] * 10, t)
            self.sub.update(t, (self.plant.eta, self.plant.nu))
            self.physics.step(self.sub.servo_outputs()[:8])
            self.t += STEP
            if k % round(every / STEP) == 0:
                eta = self.plant.eta
                out.append((t, self.floor.depth_at(eta[0], eta[1]) - eta[2], eta[2], self.sub.holds.depth))
        return out

    def surftrak(self) -> None:
        self.sub.rc_override(255, NEUTRAL + [0] * 10, self.t)
        self.sub.arm(True)
        self.fly(1.0)
        assert self.sub.set_mode(MODES["SURFTRAK"])


def test_surftrak_takes_its_target_from_the_first_reading_and_holds_it_up_a_slope():
    dive = Dive(Surface(depth=8.0, slope=0.1), depth=6.0)
    dive.surftrak()
    dive.fly(3.0)
    said = [text for _, text in dive.sub.texts if text.startswith("rangefinder target is")]
    assert len(said) == 1 and float(said[0].split()[3]) == pytest.approx(2.0, abs=0.02)
    dive.sticks = FORWARD
    track = dive.fly(40.0)
    heights = np.array([h for _, h, _, _ in track[20:]])
    climbed = track[0][2] - track[-1][2]
    assert climbed > 1.0
    assert np.sqrt(np.mean((heights - 2.0) ** 2)) < 0.1 and heights.min() > 1.8


def test_a_three_second_dropout_holds_the_depth_and_never_moves_toward_the_bottom():
    """The bottom rises under the vehicle while the sounder is silent: ArduSub holds the last depth target (the range
    target kept), and takes the range up again when the readings come back."""
    dive = Dive(Surface(depth=8.0, slope=0.1), depth=6.0)
    dive.surftrak()
    dive.fly(3.0)
    dive.sticks = FORWARD
    dive.fly(10.0)
    dive.silent_until = dive.t + 3.0
    silent = dive.fly(3.0, every=0.1)
    targets = [target for _, _, _, target in silent[12:]]       # once the filter's last second is spent
    assert max(targets) - min(targets) < 1e-6                     # held
    assert all(depth <= silent[0][2] + 0.05 for _, _, depth, _ in silent)
    assert dive.sub.surftrak.target == pytest.approx(2.0, abs=0.05)
    after = dive.fly(10.0)
    assert abs(after[-1][1] - dive.sub.surftrak.target) < 0.1


def test_the_pilot_moves_the_target_by_the_depth_changed_and_a_disarm_forgets_it():
    dive = Dive(Surface(depth=8.0), depth=5.0)
    dive.surftrak()
    dive.fly(3.0)
    first = dive.sub.surftrak.target
    start = dive.plant.eta[2]
    dive.sticks = DOWN_STICK                                       # throttle down: deeper
    dive.fly(2.0)
    dive.sticks = NEUTRAL
    dive.fly(0.5)
    moved = dive.plant.eta[2] - start
    assert moved > 0.2
    assert dive.sub.surftrak.target == pytest.approx(first - moved, abs=0.1)
    dive.sub.arm(False)
    assert dive.sub.surftrak.target is None


def test_above_surftrak_depth_it_asks_to_descend_and_takes_no_target():
    dive = Dive(Surface(depth=2.0), depth=0.3)
    dive.surftrak()
    dive.fly(3.0)
    texts = [text for _, text in dive.sub.texts]
    assert "descend below -0.500000 meters to hold range" in texts
    assert dive.sub.surftrak.target is None
