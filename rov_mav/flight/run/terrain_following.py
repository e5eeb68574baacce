"""A run's altitude and standoff legs (`rov_mav.mission.terrain`): the sounder's readings into the surface's estimate,
and the mission's depth reference replaced by the one that holds the leg's height, tick by tick.

Entering a leg, the terrain reference starts from the planned depth and velocity it takes over; leaving the last one
for a planned depth, it is flown back to the plan at the same limits and hands over once there. With the surface lost
(no accepted sounding for `LOST_AFTER`) the depth is held and the run says so; after `stop_after` s lost it stops
(Abort: the safe stop), as a pilot would not fly on blind; a bottom rising faster than the reference may climb is
climbed at the limit, and said once per episode.
"""

from __future__ import annotations

import math

import numpy as np

from rov_mav.flight.run.run_options import Abort
from rov_mav.flight.state.soundings import UP, Sounding
from rov_mav.mission.missions import Mission
from rov_mav.mission.terrain import SurfaceEstimate, TerrainReference, VerticalLimits

STOP_AFTER = 10.0                # s with the surface lost before a leg is stopped (chosen: a Ping's dropouts last
                                 # seconds; ten is long for a vehicle 1 m off a bottom it cannot see)
HANDED_BACK = 0.01               # m and m/s from the plan at which a planned depth takes over again


class TerrainFollowing:
    """`observe(soundings, depth)` with each tick's new readings; `shape(t, vehicle_t, reference, dt)` the reference
    the law flies."""

    def __init__(self, mission: Mission, limits: VerticalLimits, say, stop_after: float = STOP_AFTER):
        self.mission = mission
        self.limits = limits
        self.say = say
        self.stop_after = stop_after
        self.bottom, self.ice = SurfaceEstimate(), SurfaceEstimate(looking_up=True)
        self.reference: TerrainReference | None = None
        self.height: float = math.nan            # m: the last sounding taken in (the sounder's height)
        self.surface: float = math.nan           # m: the estimated depth of the leg's surface
        self.lost_since: float | None = None
        self._climb_said = False

    def observe(self, soundings: list[Sounding], depth: float) -> None:
        for s in soundings:
            if (self.ice if s.orientation == UP else self.bottom).update(s.t, depth, s.distance, s.quality):
                self.height = s.distance           # the sounder's height, as the estimate took it in

    def shape(self, t: float, vehicle_t: float, reference: np.ndarray, dt: float) -> np.ndarray:
        """The reference (18,) at mission time t with its depth, rate and acceleration made for the leg."""
        leg = self.mission.terrain(t) if t >= 0 else None
        if leg is None and self.reference is None:
            return reference
        if self.reference is None:
            self.reference = TerrainReference(float(reference[2]), float(reference[8]), self.limits)
        if leg is None:
            z, rate, accel = self.reference.step(dt, float(reference[2]), float(reference[8]))
            if abs(z - reference[2]) < HANDED_BACK and abs(rate - reference[8]) < HANDED_BACK:
                self.reference = None
                return reference
        else:
            z, rate, accel = self._leg(leg, vehicle_t, dt)
        out = reference.copy()
        out[2], out[8], out[14] = z, rate, accel
        return out

    def ahead(self, reference: np.ndarray, horizon: float) -> np.ndarray:
        """A reference `horizon` s later (the prediction's) with the shaped depth carried forward at its rate."""
        if self.reference is None:
            return reference
        out = reference.copy()
        r = self.reference
        out[2], out[8], out[14] = r.z + r.rate * horizon + 0.5 * r.accel * horizon ** 2, r.rate + r.accel * horizon, \
            r.accel
        return out

    def _leg(self, leg: tuple[str, float], vehicle_t: float, dt: float) -> tuple[float, float, float]:
        kind, height = leg
        standoff = kind == "standoff"
        estimate = self.ice if standoff else self.bottom
        what = "the ice" if standoff else "the bottom"
        if estimate.lost(vehicle_t):
            if self.lost_since is None:
                self.lost_since = vehicle_t
                self.say(f"{what} lost (no sounding taken for {vehicle_t - estimate.accepted_at:.1f} s): holding "
                         "the depth", "warning")
            elif vehicle_t - self.lost_since > self.stop_after:
                raise Abort(f"{what} lost for {vehicle_t - self.lost_since:.1f} s on a {kind} leg (limit "
                            f"{self.stop_after:g} s): the leg stopped")
            return self.reference.step(dt, None)
        if self.lost_since is not None:
            self.say(f"{what} found again after {vehicle_t - self.lost_since:.1f} s: {kind} {height:g} m resumed")
            self.lost_since = None
        surface, rate = estimate.at(vehicle_t)
        self.surface = surface
        step = self.reference.step(dt, self.reference.goal(surface, height, standoff), rate)
        if self.reference.climbing_at_limit and not self._climb_said:
            self.say(f"{what} rises at {-rate:.2f} m/s, faster than the {self.limits.climb:g} m/s this run climbs: "
                     "climbing at the limit", "warning")
        self._climb_said = self.reference.climbing_at_limit
        return step
