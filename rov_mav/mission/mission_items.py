"""MAVLink mission items (a QGroundControl plan's, or a vehicle's) -> a Mission, read the way ArduSub reads them.

Depth (ArduSub/commands_logic.cpp, `Sub::start_command`): a navigation item's altitude is relative to home, and home
is the water's surface, so d m below the surface is an altitude of -d m. ArduSub refuses an item above the surface
(altitude > 0: "BAD NAV ALT") and any altitude frame but relative-to-home (MAV_FRAME_GLOBAL_RELATIVE_ALT, or its
_INT twin: "BAD NAV AltFrame") or, since PR #26450 (4.5 on), above the terrain (MAV_FRAME_GLOBAL_TERRAIN_ALT, _INT:
a height above the bottom its rangefinder sees); so do we, before anything moves. A terrain-frame item becomes an
altitude leg (`rov_mav.mission.terrain`): planned at the depth before it, its depth made from the echo sounder.
`Sub::do_nav_wp`: latitude and longitude both 0 mean "where the vehicle is" (here: the previous waypoint), altitude
0 "at the current depth" (the previous waypoint's); param1 is the time to hold at the waypoint, s.

Flown: NAV_WAYPOINT (a goto, then its hold), NAV_LOITER_TIME (the same: `Sub::do_loiter_time`), DO_CHANGE_SPEED
(param2 > 0 m/s is the speed of the legs after it: `Sub::do_change_speed`). Anything else (takeoff, land, return to
launch, camera and servo commands, jumps, spline waypoints, ...) cannot be flown by this controller: such items are
listed and refused, or left out and reported when the caller asks to skip them.

Path: each leg becomes a goto segment (the same smooth stop-to-stop reference as a YAML mission's). A waypoint's
yaw (param4, degrees clockwise from north) when given is reached by the end of its leg; without one the vehicle
faces along each leg, as ArduSub's default WP_YAW_BEHAVIOR (look at the next waypoint) does, turning in place before
the leg (stop-and-turn) at TURN_RATE on average. Latitude and longitude become north/east metres on the WGS84
local tangent plane at the origin (pymap3d.geodetic2ned); the plane departs from the sea surface by r^2 / (2 R),
0.8 mm at 100 m, and the depth is taken from the altitude alone.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pymap3d

from rov_mav import config
from rov_mav.mission.missions import Mission, mission_from_dict
from rov_mav.units import wrap_angle

NAV_WAYPOINT, NAV_LOITER_TIME, DO_CHANGE_SPEED = 16, 19, 178
FLOWN = (NAV_WAYPOINT, NAV_LOITER_TIME, DO_CHANGE_SPEED)
POSITIONED = (NAV_WAYPOINT, NAV_LOITER_TIME)
RELATIVE_ALT_FRAMES = (3, 6)       # MAV_FRAME_GLOBAL_RELATIVE_ALT, MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
TERRAIN_ALT_FRAMES = (10, 11)      # MAV_FRAME_GLOBAL_TERRAIN_ALT, MAV_FRAME_GLOBAL_TERRAIN_ALT_INT
FRAME_NAMES = {0: "GLOBAL (above mean sea level)", 2: "MISSION", 5: "GLOBAL_INT (above mean sea level)",
               10: "GLOBAL_TERRAIN_ALT", 11: "GLOBAL_TERRAIN_ALT_INT"}
COMMAND_NAMES = {16: "NAV_WAYPOINT", 17: "NAV_LOITER_UNLIM", 18: "NAV_LOITER_TURNS", 19: "NAV_LOITER_TIME",
                 20: "NAV_RETURN_TO_LAUNCH", 21: "NAV_LAND", 22: "NAV_TAKEOFF", 30: "NAV_CONTINUE_AND_CHANGE_ALT",
                 31: "NAV_LOITER_TO_ALT", 82: "NAV_SPLINE_WAYPOINT", 84: "NAV_VTOL_TAKEOFF", 85: "NAV_VTOL_LAND",
                 92: "NAV_GUIDED_ENABLE", 93: "NAV_DELAY", 112: "CONDITION_DELAY", 114: "CONDITION_DISTANCE",
                 115: "CONDITION_YAW", 176: "DO_SET_MODE", 177: "DO_JUMP", 178: "DO_CHANGE_SPEED",
                 179: "DO_SET_HOME", 181: "DO_SET_RELAY", 183: "DO_SET_SERVO", 201: "DO_SET_ROI",
                 203: "DO_DIGICAM_CONTROL", 205: "DO_MOUNT_CONTROL", 206: "DO_SET_CAM_TRIGG_DIST",
                 2000: "IMAGE_START_CAPTURE", 4501: "CONDITION_GATE"}
MAX_SPEED = 1.5                    # m/s: about a BlueROV2 Heavy's top speed; a faster plan was made for an aircraft
MAX_RANGE = 10_000.0               # m from the origin: further is a plan drawn around another home
TURN_RATE = math.radians(15.0)     # rad/s, mean of a turn in place (peak 1.5x: 22.5 deg/s, under ArduSub's 60)
MIN_TURN = math.radians(1.0)       # rad: smaller heading changes are not worth a stop
MIN_TURN_LEG = 0.5                 # m: a leg shorter than this horizontally (a depth change) keeps the heading
SAME_POINT = 0.01                  # m: a waypoint this close to the previous one adds no leg
LISTED = 5                         # unflyable items named in the refusal before "and N more"


@dataclass(frozen=True)
class MissionItem:
    """One item as MISSION_ITEM_INT carries it, with x, y in degrees and z in m; NaN for an unset param.
    `label` says where it is in its source (e.g. 'mission.items[3]', 'vehicle item 3')."""

    label: str
    command: int
    frame: int
    params: tuple[float, float, float, float, float, float, float]
    kind: str = ""            # what it is when it is no MAVLink command (a complex item with no waypoints)

    @property
    def name(self) -> str:
        return self.kind or COMMAND_NAMES.get(self.command, f"command {self.command}")

    def describe(self) -> str:
        return f"{self.label} ({self.name})"


@dataclass(frozen=True)
class PlanOptions:
    """How to read a plan: origin (lat, lon deg; default the plan's home), leg speed in m/s (default the plan's),
    and whether items that cannot be flown are left out (True) or refuse the plan."""

    origin: tuple[float, float] | None = None
    speed: float | None = None
    skip_unflyable: bool = False


@dataclass(frozen=True)
class Planned:
    """What the items say, before any trajectory: where the mission sits and how fast it flies."""

    name: str
    source: str
    home: tuple[float, float] | None      # lat, lon deg of the plan's (or vehicle's) home
    speed: float | None                   # m/s, the plan's own (QGC's cruiseSpeed, the vehicle's WP_SPD)
    speed_origin: str                     # where that speed came from, for messages
    items: list[MissionItem]
    use_yaw: bool = True                  # False for a vehicle's items: ArduSub does not store a waypoint's yaw
    extra: dict = field(default_factory=dict)   # mission-file keys: description, ramp_time, environment, limits


@dataclass
class _Waypoint:
    label: str
    ned: np.ndarray           # (3,) m (a terrain-frame item's depth: the one before it, as planned)
    hold: float               # s
    yaw: float | None         # rad
    speed: float              # m/s of the leg that ends here
    altitude: float | None = None   # m above the bottom (a terrain-frame item), else None


def build_mission(planned: Planned, options: PlanOptions = PlanOptions()) -> Mission:
    """The Mission of `planned`'s items; ConfigError (one line, naming the item) for anything ArduSub would refuse,
    an item that cannot be flown (unless skipped), or a speed this vehicle cannot fly."""
    source = planned.source
    unflyable = [item for item in planned.items if item.command not in FLOWN]
    if unflyable and not options.skip_unflyable:
        named = ", ".join(item.describe() for item in unflyable[:LISTED])
        more = f" and {len(unflyable) - LISTED} more" if len(unflyable) > LISTED else ""
        raise config.ConfigError(f"{source}: cannot fly {named}{more}: only NAV_WAYPOINT, NAV_LOITER_TIME and "
                                 f"DO_CHANGE_SPEED are flown (--skip-unflyable leaves the others out)")
    origin = options.origin or planned.home
    if origin is None:
        raise config.ConfigError(f"{source}: no home position to place the waypoints around: give --origin LAT,LON")
    if options.speed is not None:
        speed = _checked_speed(options.speed, f"{source}: --plan-speed")
    elif planned.speed is not None:
        speed = _checked_speed(planned.speed, f"{source}: {planned.speed_origin}")
    else:
        raise config.ConfigError(f"{source}: no speed to fly the legs at: give --plan-speed M/S")
    waypoints = _waypoints(planned, origin, speed)
    if not waypoints:
        raise config.ConfigError(f"{source}: no waypoint to fly")
    path, labels, heading = _path(waypoints, planned.extra.get("ramp_time", 2.0))
    if not path:
        raise config.ConfigError(f"{source}: nothing to fly: one waypoint and no hold time")
    data = {"name": planned.name, **planned.extra,
            "start": {"position": [float(v) for v in waypoints[0].ned], "heading": heading}, "path": path}
    skipped = tuple(f"skipped {item.describe()}" for item in unflyable)
    return mission_from_dict(data, source, labels=labels, origin=origin, skipped=skipped)


def _checked_speed(value: float, where: str) -> float:
    if not (math.isfinite(value) and value > 0):
        raise config.ConfigError(f"{where}: speed {value:g} m/s: expected a positive speed")
    if value > MAX_SPEED:
        raise config.ConfigError(f"{where}: speed {value:g} m/s is beyond what a BlueROV2 Heavy flies ("
                                 f"{MAX_SPEED:g} m/s): set the plan's speed, or give --plan-speed")
    return value


def _waypoints(planned: Planned, origin: tuple[float, float], speed: float) -> list[_Waypoint]:
    waypoints: list[_Waypoint] = []
    for item in planned.items:
        where = f"{planned.source}: {item.describe()}"
        if item.command == DO_CHANGE_SPEED:
            if item.params[1] > 0:
                speed = _checked_speed(item.params[1], where)
        elif item.command in POSITIONED:
            previous = waypoints[-1].ned if waypoints else None
            altitude = _terrain_altitude(item, previous, where)
            ned = _position(item, origin, previous, where)
            yaw = item.params[3] if planned.use_yaw and item.command == NAV_WAYPOINT else math.nan
            hold = item.params[0] if math.isfinite(item.params[0]) else 0.0
            if hold < 0:
                raise config.ConfigError(f"{where}: hold time {hold:g} s: expected 0 or more")
            waypoints.append(_Waypoint(item.label, ned, hold,
                                       wrap_angle(math.radians(yaw)) if math.isfinite(yaw) else None, speed,
                                       altitude))
    return waypoints


def _terrain_altitude(item: MissionItem, previous: np.ndarray | None, where: str) -> float | None:
    """A terrain-frame item's height above the bottom (ArduSub reads ABOVE_TERRAIN waypoints, PR #26450, as a
    height above the terrain its rangefinder sees: `Sub::do_nav_wp`, AC_WPNav's terrain offset), else None."""
    if item.frame not in TERRAIN_ALT_FRAMES:
        return None
    if previous is None:
        raise config.ConfigError(f"{where}: a height above the bottom needs a waypoint with a depth before it "
                                 "(altitude mode Relative): the mission's start must be a place and a depth")
    alt = item.params[6]
    if not alt > 0:
        raise config.ConfigError(f"{where}: altitude {alt:g} m above the terrain: a height above the bottom is "
                                 "positive (QGC: altitude mode Terrain)")
    return float(alt)


def _position(item: MissionItem, origin: tuple[float, float], previous: np.ndarray | None,
              where: str) -> np.ndarray:
    """NED metres of a positioned item, by ArduSub's reading of its frame and altitude (a terrain-frame item at the
    depth before it: its own depth is made as it flies, `rov_mav.mission.terrain`)."""
    terrain = item.frame in TERRAIN_ALT_FRAMES
    if item.frame not in RELATIVE_ALT_FRAMES and not terrain:
        frame = FRAME_NAMES.get(item.frame, str(item.frame))
        raise config.ConfigError(f"{where}: altitude frame {frame}: ArduSub flies altitudes relative to home "
                                 f"(the surface), frame GLOBAL_RELATIVE_ALT (QGC: altitude mode Relative), or above "
                                 f"the terrain, GLOBAL_TERRAIN_ALT (QGC: Terrain)")
    lat, lon, alt = item.params[4:7]
    if terrain and previous is not None and math.isfinite(alt):
        alt = 0.0                 # at the planned depth before it; the leg's own is made from the sounder
    if not all(math.isfinite(v) for v in (lat, lon, alt)):
        raise config.ConfigError(f"{where}: no position (latitude, longitude and altitude must be numbers)")
    if alt > 0:
        raise config.ConfigError(f"{where}: altitude +{alt:g} m is above the surface: ArduSub reads an altitude "
                                 f"relative to home, the surface, so {alt:g} m deep is -{alt:g}")
    if (lat == 0 and lon == 0) or alt == 0:
        if previous is None:
            missing = "latitude and longitude 0 (where the vehicle is)" if lat == 0 and lon == 0 else \
                "altitude 0 (the depth the vehicle is at)"
            raise config.ConfigError(f"{where}: {missing} needs a waypoint before it: the start must be a place")
    if abs(lat) > 90 or abs(lon) > 180:
        raise config.ConfigError(f"{where}: latitude {lat:g}, longitude {lon:g} is not a place on Earth")
    if lat == 0 and lon == 0:
        north, east = previous[0], previous[1]
    else:
        north, east, _ = pymap3d.geodetic2ned(lat, lon, 0.0, origin[0], origin[1], 0.0)
        if math.hypot(north, east) > MAX_RANGE:
            raise config.ConfigError(f"{where}: {math.hypot(north, east) / 1000:.1f} km from the origin "
                                     f"{origin[0]:g}, {origin[1]:g}: give --origin near the dive site")
    depth = previous[2] if alt == 0 else -alt
    return np.array([float(north), float(east), float(depth)])


def _path(waypoints: list[_Waypoint], ramp_time: float) -> tuple[list[dict], list[str], float]:
    """The mission file's path entries (goto / hold), the item label of each, and the start heading."""
    first = waypoints[0]
    heading = first.yaw if first.yaw is not None else _first_bearing(waypoints)
    start_heading = heading
    path: list[dict] = []
    labels: list[str] = []

    here: float | None = None            # the height above the bottom held where the vehicle is (None: a depth)

    def turn_to(target: float, label: str) -> None:
        nonlocal heading
        change = wrap_angle(target - heading)
        if abs(change) > MIN_TURN:
            path.append({"hold": max(abs(change) / TURN_RATE, ramp_time), "heading": target,
                         **({"altitude": here} if here is not None else {})})
            labels.append(f"{label} (turn)")
            heading = target

    if first.hold > 0:
        path.append({"hold": first.hold})
        labels.append(first.label)
    position = first.ned
    for wp in waypoints[1:]:
        delta = wp.ned - position
        if np.linalg.norm(delta) >= SAME_POINT:
            if wp.yaw is None and math.hypot(delta[0], delta[1]) >= MIN_TURN_LEG:
                turn_to(math.atan2(delta[1], delta[0]), wp.label)
            entry = {"goto": [float(v) for v in wp.ned], "speed": wp.speed}
            if wp.altitude is not None:
                entry = {"goto": [float(v) for v in wp.ned[:2]], "speed": wp.speed, "altitude": wp.altitude}
            if wp.yaw is not None:
                entry["heading"] = wp.yaw
                heading = wp.yaw
            path.append(entry)
            labels.append(wp.label)
            position = wp.ned
        elif wp.yaw is not None:
            turn_to(wp.yaw, wp.label)
        here = wp.altitude
        if wp.hold > 0:
            path.append({"hold": wp.hold, **({"altitude": here} if here is not None else {})})
            labels.append(wp.label)
    return path, labels, start_heading


def _first_bearing(waypoints: list[_Waypoint]) -> float:
    """The heading of the first leg long enough to face along (0, north, if none is)."""
    for a, b in zip(waypoints, waypoints[1:]):
        delta = b.ned - a.ned
        if math.hypot(delta[0], delta[1]) >= MIN_TURN_LEG:
            return math.atan2(delta[1], delta[0])
    return 0.0
