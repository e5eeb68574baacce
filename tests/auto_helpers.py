"""Test support for AUTO on the built-in vehicle: mission items as the vehicle stores them, and a dive of its
autopilot, thrusters and plant over a bottom with an echo sounder, in process (no sockets)."""

from __future__ import annotations

import numpy as np

from rov_mav.model.environment import Environment
from rov_mav.model.plant import Plant
from rov_mav.model.seafloor import Surface
from rov_mav.model.thrusters import load_t200
from rov_mav.model.vehicle import load_vehicle
from rov_mav.units import lat_lon
from sim_bridge.autopilot.ardusub import ArduSub
from sim_bridge.autopilot.params import Params
from sim_bridge.gcs.missions import Item
from sim_bridge.hardware.battery import Battery
from sim_bridge.hardware.physics import Physics
from sim_bridge.navigation.echo_sounder import EchoSounder

ORIGIN = (-35.363261, 149.16523, 0.0)          # the bridge's default --origin
STEP = 0.0025
WAYPOINT = 16
TERRAIN, RELATIVE = 10, 3                       # MAV_FRAME_GLOBAL_TERRAIN_ALT, MAV_FRAME_GLOBAL_RELATIVE_ALT
HOME = Item(0, WAYPOINT, (0.0, 0.0, 0.0, 0.0), round(ORIGIN[0] * 1e7), round(ORIGIN[1] * 1e7), ORIGIN[2])


def lat_lon_e7(north: float, east: float) -> tuple[int, int]:
    lat, lon = lat_lon(north, east, ORIGIN)
    return round(lat * 1e7), round(lon * 1e7)


def item(north: float, east: float, alt: float, frame: int = TERRAIN, hold: float = 0.0,
         command: int = WAYPOINT) -> Item:
    """A positioned item as `sim_bridge.gcs.missions` stores it: `north`, `east` m from the origin, `alt` m."""
    return Item(frame, command, (float(hold), 0.0, 0.0, 0.0), *lat_lon_e7(north, east), alt)


class Dive:
    """The autopilot (its `mission` the list `items`, home first), its thrusters and the plant over `floor`, with an
    echo sounder's readings handed to the autopilot as the bridge's router does; `quality(t, q)` may change each
    reading's signal quality, and readings in [silent[0], silent[1]) are not delivered."""

    def __init__(self, floor: Surface, depth: float, items: list, sounder="ideal", **params):
        vehicle = load_vehicle()
        self.floor = floor
        self.plant = Plant(vehicle, Environment(), eta0=np.array([0, 0, depth, 0, 0, 0.0]))
        self.physics = Physics(vehicle, self.plant, Battery(), load_t200(), STEP)
        p = Params()
        for name, value in {"FS_PILOT_INPUT": 0, "FS_GCS_ENABLE": 0, "RNGFND1_TYPE": 10, **params}.items():
            p.set(name, value)
        self.items = [HOME, *items]
        self.sub = ArduSub(p, origin=ORIGIN, mission=lambda: self.items)
        self.sounder = EchoSounder(sounder, 0, floor, None)
        self.t = 0.0
        self.silent = (np.inf, -np.inf)
        self.quality = lambda t, q: q

    def height(self) -> float:
        eta = self.plant.eta
        return float(self.floor.depth_at(eta[0], eta[1]) - eta[2])

    def fly(self, seconds: float, every: float = 0.1) -> list[tuple[float, np.ndarray, float]]:
        """(t, true eta, true height) every `every` s."""
        out = []
        sample = round(every / STEP)
        for k in range(round(seconds / STEP)):
            t = self.t
            for reading in self.sounder.sample(t, self.plant.eta, self.plant.nu):
                if self.silent[0] <= t < self.silent[1]:
                    continue
                for msg, _ in self.sounder.messages(reading, int(t * 1000)):
                    self.sub.rangefinder.handle(msg.orientation, msg.current_distance, msg.min_distance,
                                                msg.max_distance, self.quality(t, msg.signal_quality), msg.type, t)
            self.sub.update(t, (np.array(self.plant.eta), np.array(self.plant.nu)))
            self.physics.step(self.sub.servo_outputs()[:8])
            self.t += STEP
            if k % sample == 0:
                out.append((t, np.array(self.plant.eta), self.height()))
        return out

    def texts(self) -> list[str]:
        return [text for _, text in self.sub.texts]
