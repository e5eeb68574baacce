"""What a dive is measured against: when its mission started, and the path of the vehicle's own mission.

Mission start (vehicle s since boot): given by the user, else as a rov-mav run announced it on the link
(`runlog.mission_start_text`), else the first arming, else the first state in the log.

The vehicle's mission (the items a ground station uploaded or downloaded): its positioned items (NAV_WAYPOINT,
NAV_LOITER_*, NAV_SPLINE_WAYPOINT) in local NED, where ArduSub steers to them (ArduSub/commands_logic.cpp,
`Sub::start_command`: altitudes relative to home, the surface, so d m deep is -d; lat = lon = 0 means where the
vehicle is, here the previous waypoint). The target is placed in the EKF's frame, that of LOCAL_POSITION_NED: north
and east around the EKF origin (GPS_GLOBAL_ORIGIN; else around home at its own local x, y) as
`Location::get_distance_NE` computes them, and down = home's local z (HOME_POSITION) - altitude, as
`Location::get_alt_cm` turns an altitude above home into one above the origin (libraries/AP_Common/Location.cpp).
"""

from __future__ import annotations

import math

import numpy as np

from rov_mav.flight.runlog import parse_mission_start
from rov_mav.review.dive import Dive, MissionItem

LOCATION_SCALING_FACTOR = 0.011131884502145034     # m per 1e-7 degree of latitude (AP_Common/Location.h)
POSITIONED = {16: "NAV_WAYPOINT", 17: "NAV_LOITER_UNLIM", 18: "NAV_LOITER_TURNS", 19: "NAV_LOITER_TIME",
              82: "NAV_SPLINE_WAYPOINT"}


def mission_start(dive: Dive, given: float | None = None) -> tuple[float | None, str]:
    """(t0 in vehicle s since boot, how it was found); None when the log has no state at all."""
    if given is not None:
        return given, "given (--mission-start)"
    for _, _, _, text in dive.texts:
        if (t0 := parse_mission_start(text)) is not None:
            return t0, "announced by the rov-mav run on the link"
    armed = np.flatnonzero(dive.armed)
    if armed.size and dive.clock_t.size:
        return float(np.interp(dive.heartbeat_wall[armed[0]], dive.clock_wall, dive.clock_t)), "the first arming"
    if dive.state_t.size:
        return float(dive.state_t[0]), "the first state in the log"
    return None, "no state in the log"


def waypoint_path(dive: Dive) -> tuple[np.ndarray | None, list[str], str]:
    """The vehicle's mission as waypoints: (M, 3) NED (None if none can be placed), a label per waypoint, and a
    note saying where it came from or why it could not be placed."""
    items = [item for item in dive.mission if item.command in POSITIONED and item.seq > 0]   # item 0 is home
    if not items:
        return None, [], "no positioned mission item in the log" if dive.mission else "no mission in the log"
    anchor = _anchor(dive)
    if anchor is None:
        return None, [], (f"{len(items)} waypoints found, but neither GPS_GLOBAL_ORIGIN nor HOME_POSITION to place "
                          "them")
    lat0, lon0, north0, east0 = anchor
    home_down = float(dive.home.z) if dive.home is not None else 0.0
    points, labels, previous = [], [], None
    for item in items:
        if item.frame not in (3, 6):        # MAV_FRAME_GLOBAL_RELATIVE_ALT(_INT): all ArduSub flies
            continue
        if item.lat == 0 and item.lon == 0 and previous is not None:
            north, east = previous[0], previous[1]
        else:
            north, east = _north_east(item, lat0, lon0)
            north, east = north + north0, east + east0
        depth = previous[2] if item.alt == 0 and previous is not None else home_down - item.alt
        previous = (north, east, depth)
        points.append(previous)
        labels.append(f"item {item.seq} ({POSITIONED[item.command]})")
    if not points:
        return None, [], "the mission's waypoints are in altitude frames ArduSub does not fly"
    whole = "" if dive.mission_complete else " (only part of the mission was in the log)"
    surface = "" if dive.home is not None else "; no HOME_POSITION: the surface taken at the EKF origin's depth"
    return np.array(points), labels, f"the vehicle's mission: {len(points)} waypoints{whole}{surface}"


def _anchor(dive: Dive) -> tuple[float, float, float, float] | None:
    """(lat, lon in degrees of a point, its local north, east in m)."""
    if dive.origin is not None:
        return dive.origin.latitude * 1e-7, dive.origin.longitude * 1e-7, 0.0, 0.0
    if dive.home is not None:
        return dive.home.latitude * 1e-7, dive.home.longitude * 1e-7, float(dive.home.x), float(dive.home.y)
    return None


def _north_east(item: MissionItem, lat0: float, lon0: float) -> tuple[float, float]:
    dlon = (item.lon - lon0 + 180.0) % 360.0 - 180.0
    scale = max(math.cos(math.radians(0.5 * (item.lat + lat0))), 0.01)
    return (item.lat - lat0) * 1e7 * LOCATION_SCALING_FACTOR, dlon * 1e7 * LOCATION_SCALING_FACTOR * scale


def path_deviation(positions: np.ndarray, path: np.ndarray, chunk: int = 4096) -> np.ndarray:
    """Distance (m) of each position (N, 3) to the polyline through `path` (M, 3): the cross-track error."""
    if len(path) == 1:
        return np.linalg.norm(positions - path[0], axis=1)
    a, b = path[:-1], path[1:]                                   # (S, 3) legs
    ab = b - a
    length2 = np.maximum(np.sum(ab**2, axis=1), 1e-12)
    out = np.empty(len(positions))
    for k in range(0, len(positions), chunk):                    # (chunk, S, 3) at a time
        p = positions[k:k + chunk, None]
        s = np.clip(np.einsum("nsk,sk->ns", p - a[None], ab) / length2, 0.0, 1.0)
        out[k:k + chunk] = np.min(np.linalg.norm(p - (a[None] + s[..., None] * ab[None]), axis=2), axis=1)
    return out
