"""The vehicle's true position, where a simulator puts it on the link: SIM_STATE, as ArduPilot SITL sends it
(`SITL::SIM::sim_state_send`, from `GCS_MAVLINK::send_sim_state`), and the built-in vehicle does the same.

SIM_STATE gives latitude and longitude (lat_int/lon_int in 1e-7 degrees when present: the float fields are too coarse
for centimetres) and altitude; with the EKF origin (GPS_GLOBAL_ORIGIN) or, failing it, HOME_POSITION they become the
NED position LOCAL_POSITION_NED is relative to, on the same flat earth the vehicle uses. Over a bottom (or under
ice) the built-in vehicle also sends the true height above it (NAMED_VALUE_FLOAT SimHeight, SimIceGap). A real
vehicle sends no SIM_STATE: then there is no truth, and nothing is reported against it. SIM_STATE carries no
timestamp: it is taken as of the vehicle time it arrives at. Pure: no I/O.
"""

from __future__ import annotations

import numpy as np

from rov_mav.units import north_east


class Truth:
    """`update(msg, t)` with any message; `position` the latest true NED position (None until an origin and a
    SIM_STATE have both arrived), `t` the vehicle time it arrived at."""

    def __init__(self):
        self.origin: tuple[float, float, float] | None = None   # lat deg, lon deg, alt m
        self.from_home = False
        self.position: np.ndarray | None = None
        self.t: float | None = None
        self.height: float | None = None     # m: the true height above the bottom (the built-in vehicle's SimHeight)
        self.ice_gap: float | None = None    # m: the true distance below the ice (SimIceGap)
        self.height_t: float | None = None

    def update(self, msg, t: float) -> bool:
        """Take one message at vehicle time t; True when it gives a new true position."""
        kind = msg.get_type()
        if kind == "GPS_GLOBAL_ORIGIN":
            self.origin, self.from_home = (msg.latitude * 1e-7, msg.longitude * 1e-7, msg.altitude * 1e-3), False
        elif kind == "HOME_POSITION" and (self.origin is None or self.from_home):
            self.origin, self.from_home = (msg.latitude * 1e-7, msg.longitude * 1e-7, msg.altitude * 1e-3), True
        elif kind == "NAMED_VALUE_FLOAT" and msg.name in ("SimHeight", "SimIceGap"):
            if msg.name == "SimHeight":
                self.height = float(msg.value)
            else:
                self.ice_gap = float(msg.value)
            self.height_t = t
        elif kind == "SIM_STATE" and self.origin is not None:
            lat = msg.lat_int * 1e-7 if msg.lat_int else msg.lat
            lon = msg.lon_int * 1e-7 if msg.lon_int else msg.lon
            self.position = np.array([*north_east(lat, lon, self.origin), self.origin[2] - msg.alt])
            self.t = t
            return True
        return False
