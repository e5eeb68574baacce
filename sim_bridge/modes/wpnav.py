"""AC_WPNav's straight leg, as ArduSub's AUTO flies one from waypoint to waypoint (`sim_bridge.modes.auto`).

Re-implemented from ArduPilot's libraries/AC_WPNav/AC_WPNav.cpp (a 4.7-era copy, AC_WPNav in metres) and
libraries/AP_Math/control.cpp:
- `wp_and_spline_init`: the origin and destination both the stopping point, above the EKF origin (not the terrain),
  the destination counted as reached; WPNAV_RADIUS (4.7: WP_RADIUS_M) no less than 5 cm.
- `set_wp_destination_NEU_m`: a navigator not updated in the last 200 ms (`is_active`) or interrupted before its
  destination starts again from the stopping point; the new leg starts at the previous destination. A leg whose
  altitude frame differs from the previous one's converts its origin with the terrain offset, and fails without one
  (the caller: "Terrain data (rangefinder) not available"); two terrain legs in a row need none to start.
- The terrain offset (`get_terrain_offset_m`, `get_terrain_source`): in ArduSub the rangefinder's
  (ArduSub/sensors.cpp `Sub::read_rangefinder` hands `set_rangefinder_terrain_offset_cm` its enabled flag, its
  alt_healthy and the bottom's height under the EKF origin from the filtered range); none while the rangefinder is
  not healthy. Here it is the bottom's depth, `Rangefinder.terrain_depth`, while `Rangefinder.healthy`.
- `advance_wp_target_along_track`: on a terrain leg without a terrain offset the target does not move and it returns
  false (`update_wpnav` reports it: ArduSub's terrain failsafe counts it). The target moves along the straight line
  at the leg's speed: WPNAV_SPEED / WPNAV_SPEED_UP / WPNAV_SPEED_DN as `kinematic_limit` combines them along the
  leg's direction, WPNAV_ACCEL likewise; its time slowed by the track scalar, 0.05 + (the vehicle's speed along the
  track - PSC_POSXY_P x the target's lead) / the target's speed, clamped to 0..1 and filtered with a time constant
  of WPNAV_ACCEL / WPNAV_JERK (the feed-forward velocity is not scaled, as ArduPilot's is not). The destination is
  reached once the target has arrived and the vehicle is within the radius of it in three dimensions, in the leg's
  frame (on a terrain leg the height above the bottom).
- AP_Math `stopping_distance` (the inverse of `sqrt_controller`) and AC_PosControl `get_stopping_point_NE_m` /
  `get_stopping_point_U_m`: where the vehicle would stop from its velocity.
Left out: the S-curve's jerk-limited profile (the target here accelerates at WPNAV_ACCEL and brakes to stop at the
destination: a trapezoid), fast waypoints and the corner to the next leg (4.7's `do_nav_wp` no longer asks for
them: every waypoint is a stop), splines, WPNAV_TER_MARGIN's slowing (10 m by default) and the input shaping of the
terrain offset (AC_PosControl's; the depth target follows the rangefinder's bottom directly, as GUIDED's terrain
target does), WPNAV_RFND_USE (always on, its default).

Coordinates: (north, east, up) m from the EKF origin, up = -depth on a depth leg and the height above the bottom on
a terrain leg; parameters by their 4.5 names and units (cm), as `Params.guided_gains` gives them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

RADIUS_MIN = 0.05              # m: WPNAV_WP_RADIUS_MIN_CM
ACTIVE_FOR = 0.2               # s: `is_active`, updated within the last 200 ms
JERK = 1.0                     # m/s/s/s: WPNAV_JERK's default, the track scalar's time constant WPNAV_ACCEL / it
CM = 0.01


def stopping_distance(speed: float, p: float, accel: float) -> float:
    """AP_Math `stopping_distance` (`inv_sqrt_controller`): the distance the square-root controller of gain p and
    deceleration `accel` takes to bring `speed` to rest (signed as the speed)."""
    if accel > 0 and p == 0:
        return math.copysign(speed * speed / (2.0 * accel), speed)
    if accel <= 0:
        return speed / p if p != 0 else 0.0
    if abs(speed) < accel / p:
        return speed / p
    distance = 0.5 * accel / (p * p) + speed * speed / (2.0 * accel)
    return math.copysign(distance, speed)


def kinematic_limit(direction: np.ndarray, along_ne: float, up: float, down: float) -> float:
    """AP_Math `kinematic_limit`: the largest magnitude along `direction` (north, east, up) that keeps its horizontal
    part within `along_ne` and its vertical part within `up` (climbing) or `down` (descending)."""
    length = float(np.linalg.norm(direction))
    if length == 0:
        return 0.0
    unit = direction / length
    horizontal, vertical = math.hypot(unit[0], unit[1]), unit[2]
    vertical_limit = up if vertical > 0 else down
    if horizontal == 0:
        return vertical_limit
    if vertical == 0:
        return along_ne
    return min(along_ne / horizontal, vertical_limit / abs(vertical))


def stopping_point(eta: np.ndarray, v_ned: np.ndarray, gains) -> np.ndarray:
    """(north, east, up) where the vehicle at `eta` moving at `v_ned` would stop (AC_PosControl
    `get_stopping_point_NE_m`, `get_stopping_point_U_m`): horizontally along its velocity (capped at WPNAV_SPEED)
    by PSC_POSXY_P and WPNAV_ACCEL, vertically by PSC_POSZ_P and WPNAV_ACCEL_Z."""
    point = np.array([eta[0], eta[1], -eta[2]], dtype=float)
    speed = math.hypot(v_ned[0], v_ned[1])
    if speed > 0:
        capped = min(speed, gains["WPNAV_SPEED"] * CM)
        distance = stopping_distance(capped, gains["PSC_POSXY_P"], gains["WPNAV_ACCEL"] * CM)
        point[:2] += np.asarray(v_ned[:2]) / speed * distance
    point[2] += stopping_distance(-float(v_ned[2]), gains["PSC_POSZ_P"], gains["WPNAV_ACCEL_Z"] * CM)
    return point


@dataclass(frozen=True)
class Limits:
    """The navigator's parameters in m, m/s, m/s/s (`from_gains`: from `Params.guided_gains`)."""

    speed: float               # WPNAV_SPEED
    speed_up: float            # WPNAV_SPEED_UP
    speed_down: float          # WPNAV_SPEED_DN
    accel: float               # WPNAV_ACCEL
    accel_z: float             # WPNAV_ACCEL_Z
    radius: float              # WPNAV_RADIUS, at least RADIUS_MIN
    p: float                   # PSC_POSXY_P, the track scalar's gain

    @classmethod
    def from_gains(cls, g) -> "Limits":
        """As ArduPilot reads them: the speeds and accelerations by their size (`kinematic_limit`'s fabsf)."""
        return cls(*(abs(g[name]) * CM for name in ("WPNAV_SPEED", "WPNAV_SPEED_UP", "WPNAV_SPEED_DN", "WPNAV_ACCEL",
                                                    "WPNAV_ACCEL_Z")),
                   max(g["WPNAV_RADIUS"] * CM, RADIUS_MIN), g["PSC_POSXY_P"])


class WaypointNav:
    """One boot's waypoint navigator: the leg (origin, destination, frame), the target's progress along it, and
    whether the destination was reached."""

    def __init__(self):
        self.origin = np.zeros(3)
        self.destination = np.zeros(3)
        self.terrain = False           # `_is_terrain_alt`: up is the height above the bottom
        self.reached = True            # `_flags.reached_destination`
        self.last_update = -math.inf   # s: `_wp_last_update_ms`
        self.travelled = 0.0           # m of the leg the target has covered
        self.speed = 0.0               # m/s of the target along the leg
        self.scalar = 1.0              # `_track_dt_scalar`

    def init(self, stop: np.ndarray, t: float) -> None:
        """`wp_and_spline_init`: hold the stopping point (above the EKF origin), the destination counted as reached."""
        self.origin = np.array(stop, dtype=float)
        self.destination = self.origin.copy()
        self.terrain = False
        self.reached = True
        self.travelled = self.speed = 0.0
        self.scalar = 1.0
        self.last_update = t

    def set_destination(self, destination, terrain: bool, terrain_depth: float | None, stop: np.ndarray,
                        t: float) -> bool:
        """`set_wp_destination_NEU_m`: a leg from the previous destination (or from `stop` when interrupted) to
        `destination` (north, east, up in the frame `terrain` says); False, and nothing changed but a restart, when
        the frames differ and there is no terrain offset (`terrain_depth` None)."""
        if t - self.last_update >= ACTIVE_FOR or not self.reached:
            self.init(stop, t)
        origin = self.destination.copy()
        if terrain != self.terrain:
            if terrain_depth is None:
                return False
            origin[2] += terrain_depth if terrain else -terrain_depth   # height = up + bottom depth
        self.origin, self.destination, self.terrain = origin, np.array(destination, dtype=float), terrain
        self.travelled = self.speed = 0.0
        self.reached = False
        return True

    @property
    def length(self) -> float:
        return float(np.linalg.norm(self.destination - self.origin))

    def bearing(self) -> float:
        """rad: the leg's bearing from its origin to its destination (`get_bearing_cd`: north for a leg without a
        horizontal part)."""
        leg = self.destination - self.origin
        return math.atan2(leg[1], leg[0]) % (2 * math.pi)

    def advance(self, position: np.ndarray, velocity: np.ndarray, terrain_depth: float | None, limits: Limits,
                t: float, dt: float) -> tuple[np.ndarray, np.ndarray] | None:
        """`advance_wp_target_along_track` for one loop: the vehicle's (north, east, up = -depth) position and
        velocity, the bottom's depth if known; the target's position (in the leg's frame) and velocity, or None
        when a terrain leg has no terrain offset (the target stays where it was)."""
        self.last_update = t
        here = np.array(position, dtype=float)
        if self.terrain:
            if terrain_depth is None:
                return None
            here[2] += terrain_depth
        leg = self.destination - self.origin
        length = float(np.linalg.norm(leg))
        unit = leg / length if length > 0 else np.zeros(3)
        target = self.origin + unit * self.travelled
        if self.speed > 0:
            lead = float(np.dot(target - here, unit))
            scalar = min(max(0.05 + (float(np.dot(velocity, unit)) - limits.p * lead) / self.speed, 0.0), 1.0)
        else:
            scalar = 1.0
        self.scalar += (scalar - self.scalar) * min(dt * JERK / max(limits.accel, 1e-6), 1.0)
        if length > 0:
            top = kinematic_limit(leg, limits.speed, limits.speed_up, limits.speed_down)
            accel = kinematic_limit(leg, limits.accel, limits.accel_z, limits.accel_z)
            step = dt * self.scalar
            braking = math.sqrt(2.0 * accel * max(length - self.travelled, 0.0))
            self.speed = min(self.speed + accel * step, top, braking)
            self.travelled = min(self.travelled + self.speed * step, length)
            if self.travelled >= length:
                self.speed = 0.0
        target = self.origin + unit * self.travelled
        if not self.reached and self.travelled >= length and \
                float(np.linalg.norm(here - self.destination)) <= limits.radius:
            self.reached = True
        return target, unit * self.speed
