"""What a dive is measured against: when its mission started, and the path of the vehicle's own mission.

Mission start (vehicle s since boot): given by the user, else as a rov-mav run announced it on the link
(`runlog.mission_start_text`), else the first arming, else the first state in the log.

The vehicle's mission (the items a ground station uploaded or downloaded) is read as `run --mission-from-vehicle`
reads it (`mission.mission_items`: ArduSub's altitude convention, lat = lon = 0 for "where the vehicle is", what
is flown and what is left out), around the EKF origin (GPS_GLOBAL_ORIGIN: the origin of LOCAL_POSITION_NED; else
home, shifted by its own local x, y), and then placed where ArduSub steers: an altitude above home becomes one above
the origin through home's altitude (`Location::get_alt_cm`, libraries/AP_Common/Location.cpp), so down = home's
local z (HOME_POSITION) - altitude.
"""

from __future__ import annotations

import numpy as np

from rov_mav.config import ConfigError
from rov_mav.flight.record.runlog import parse_mission_start
from rov_mav.mission.mission_items import Planned, PlanOptions, build_mission
from rov_mav.review.dive import Dive

NOMINAL_SPEED = 0.5          # m/s: the legs' speed, which does not change where they go
SAME_POINT = 1e-3            # m: successive path points closer than this are one waypoint


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
    if dive.clock_t.size:
        return float(dive.clock_t[0]), "the start of the log"
    return None, "no state in the log"


def waypoint_path(dive: Dive, source: str) -> tuple[np.ndarray | None, list[str], str]:
    """The vehicle's mission as waypoints: (M, 3) NED in the EKF's frame (None if none can be placed), a label per
    waypoint, and a note saying what they are or why they could not be placed."""
    items = [item for seq, item in dive.mission.items() if seq > 0]          # item 0 is home
    if not items:
        return None, [], "no mission in the log"
    anchor = dive.origin or dive.home
    if anchor is None:
        return None, [], f"{len(items)} mission items, but neither GPS_GLOBAL_ORIGIN nor HOME_POSITION to place them"
    planned = Planned(name="vehicle_mission", source=f"{source}: the vehicle's mission", home=None,
                      speed=NOMINAL_SPEED, speed_origin="nominal", items=items, use_yaw=False)
    origin = (anchor.latitude * 1e-7, anchor.longitude * 1e-7)
    try:
        mission = build_mission(planned, PlanOptions(origin=origin, skip_unflyable=True))
    except ConfigError as exc:
        return None, [], f"the vehicle's mission cannot be placed: {exc}"
    shift = np.zeros(3) if anchor is dive.origin else np.array([anchor.x, anchor.y, 0.0])
    shift[2] = float(dive.home.z) if dive.home is not None else 0.0
    points = [(f"{items[0].label} (start)", mission.segments[0].p0[:3])]
    points += [(label, seg.p1[:3]) for label, seg in zip(mission.labels, mission.segments)]
    path, labels = [], []
    for label, point in points:
        if not path or np.linalg.norm(point - path[-1]) > SAME_POINT:
            path.append(point)
            labels.append(label)
    whole = "" if dive.mission_complete else " (only part of the mission was in the log)"
    surface = "" if dive.home is not None else "; no HOME_POSITION: the surface taken at the EKF origin's depth"
    left_out = f"; left out: {', '.join(s.removeprefix('skipped ') for s in mission.skipped)}" if mission.skipped \
        else ""
    return (np.array(path) + shift, labels,
            f"the vehicle's mission: {len(path)} waypoints{whole}{surface}{left_out}")


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
