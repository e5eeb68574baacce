"""A leg's depth made online from an echo sounder: the bottom (or the ice) under the vehicle estimated from its depth
and the ranges, and the depth reference that holds the leg's altitude (or standoff) within what the vehicle can fly.

`SurfaceEstimate`: a constant-velocity Kalman filter of the surface's depth b and its rate b' (the bottom rising
under a moving vehicle is a rate), fed depth + range (a down-looking sounder; depth - range looking up at ice) for
each sounding of signal quality at least QUALITY_MIN; a sounding more than GATE standard deviations from the
prediction is held back (a false lock on kelp reads short for a moment), and GATE_COUNT in a row that agree with
each other restart the filter at their level (the bottom did step: a step is taken a second late, which a cone that
sees a step ahead of the vehicle mostly covers). Its standard deviation is the estimate's own
confidence; it counts as lost LOST_AFTER s after its last accepted sounding.

`TerrainReference`: the goal depth is the surface less the altitude (plus the standoff under ice), never within
MIN_HEIGHT of the surface and never past the run's max_depth; the reference depth follows the goal with the
surface's rate fed forward and a square-root braking law, its speed limited to `climb` up and `descent` down and its
acceleration to `accel`, so the law is asked for nothing the vehicle cannot fly. While the surface is lost it holds:
the rate brakes to 0 at `accel` and the depth stays. `climbing_at_limit` says when the goal rises faster than the
reference may climb.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

QUALITY_MIN = 50                 # signal quality (%) of a sounding used (chosen: below it a Ping's lock is doubtful)
GATE = 4.0                       # standard deviations: a sounding further from the prediction is held back
GATE_COUNT = 10                  # held-back soundings in a row, agreeing within GATE_AGREE, that move the estimate
                                 # (a second of a Ping; tools/terrain_estimate.py, a Ping at 0.001 false locks a
                                 # ping: 5 gave 4.9 cm RMS, 69 cm at worst; 10 3.8 and 35; 20 3.9 and 40)
GATE_AGREE = 0.15                # m
LOST_AFTER = 1.5                 # s without an accepted sounding: the surface is lost
SURFACE_ACCEL = 0.05             # m/s^2 per sqrt(s): how fast the surface's rate may change under a moving vehicle
MIN_HEIGHT = 0.3                 # m: never nearer the surface than this


def sounding_noise(distance: float) -> float:
    """m: the standard deviation assumed of one sounding (a Ping: a few mm plus about 0.5 % of the range, chosen
    above the real log's 0.2 %)."""
    return 0.01 + 0.005 * distance


class SurfaceEstimate:
    """The depth of the surface a sounder sees, and its rate, from (vehicle time, vehicle depth, range, quality)."""

    def __init__(self, looking_up: bool = False):
        self.sign = -1.0 if looking_up else 1.0
        self.x: np.ndarray | None = None          # (depth m, rate m/s)
        self.p = np.zeros((2, 2))
        self.t: float | None = None
        self.accepted_at = -math.inf
        self._held: list[float] = []

    def update(self, t: float, depth: float, distance: float, quality: int) -> bool:
        """One sounding; True when it was taken in."""
        if quality < QUALITY_MIN or not math.isfinite(distance) or distance <= 0:
            return False
        z = depth + self.sign * distance
        r = sounding_noise(distance) ** 2
        if self.x is None or t - self.accepted_at > LOST_AFTER:
            self._restart(t, z, r)
            return True
        self._predict(t)
        innovation = z - self.x[0]
        s = self.p[0, 0] + r
        if innovation * innovation > GATE * GATE * s:
            self._held = [*self._held[-(GATE_COUNT - 1):], z]
            if len(self._held) == GATE_COUNT and max(self._held) - min(self._held) <= GATE_AGREE:
                self._restart(t, float(np.mean(self._held)), r)
                return True
            return False
        self._held = []
        k = self.p[:, 0] / s
        self.x = self.x + k * innovation
        self.p = self.p - np.outer(k, self.p[0, :])
        self.accepted_at = t
        return True

    def _restart(self, t: float, z: float, r: float) -> None:
        self.x = np.array([z, 0.0])
        self.p = np.diag([r, 0.05 ** 2])
        self.t = self.accepted_at = t
        self._held = []

    def _predict(self, t: float) -> None:
        dt = max(t - self.t, 0.0)
        f = np.array([[1.0, dt], [0.0, 1.0]])
        q = SURFACE_ACCEL ** 2 * np.array([[dt ** 3 / 3, dt ** 2 / 2], [dt ** 2 / 2, dt]])
        self.x = f @ self.x
        self.p = f @ self.p @ f.T + q
        self.t = t

    def lost(self, t: float) -> bool:
        return self.x is None or t - self.accepted_at > LOST_AFTER

    def at(self, t: float) -> tuple[float, float]:
        """(depth, rate) of the surface predicted to vehicle time t."""
        dt = max(t - self.t, 0.0)
        return float(self.x[0] + self.x[1] * dt), float(self.x[1])

    @property
    def std(self) -> float:
        """m: the estimate's standard deviation."""
        return math.sqrt(max(self.p[0, 0], 0.0))


@dataclass(frozen=True)
class VerticalLimits:
    """What the reference may ask of the vehicle vertically (chosen well inside a BlueROV2 Heavy's ~1 m/s)."""

    climb: float = 0.3           # m/s up
    descent: float = 0.3         # m/s down
    accel: float = 0.3           # m/s^2
    max_depth: float | None = None


class TerrainReference:
    """The depth reference (z, z', z'') of a leg holding `height` above the bottom (`standoff` False) or below the
    ice (True), started at the reference it takes over from."""

    def __init__(self, z: float, rate: float, limits: VerticalLimits):
        self.z, self.rate, self.accel = z, rate, 0.0
        self.limits = limits
        self.climbing_at_limit = False

    def goal(self, surface: float, height: float, standoff: bool) -> float:
        """The depth holding `height` from the surface, within MIN_HEIGHT of it at most and the max depth."""
        if standoff:
            return max(surface + height, surface + MIN_HEIGHT) if self.limits.max_depth is None else \
                min(max(surface + height, surface + MIN_HEIGHT), self.limits.max_depth)
        goal = min(surface - height, surface - MIN_HEIGHT)
        return goal if self.limits.max_depth is None else min(goal, self.limits.max_depth)

    def step(self, dt: float, goal: float | None, goal_rate: float = 0.0) -> tuple[float, float, float]:
        """Advance dt s toward `goal` moving at `goal_rate` (None: hold where it is); (z, z', z'')."""
        lim = self.limits
        if goal is None:
            wanted = 0.0
            self.climbing_at_limit = False
        else:
            error = goal - self.z
            braking = math.copysign(math.sqrt(2.0 * lim.accel * abs(error)), error) if error else 0.0
            linear = 2.0 * error                       # near the goal: a gentle P, not the square root's steepness
            wanted = goal_rate + (braking if abs(braking) < abs(linear) else linear)
            self.climbing_at_limit = goal_rate < -lim.climb
        wanted = min(max(wanted, -lim.climb), lim.descent)
        change = min(max(wanted - self.rate, -lim.accel * dt), lim.accel * dt)
        self.accel = change / dt if dt > 0 else 0.0
        self.rate += change
        self.z += self.rate * dt
        return self.z, self.rate, self.accel
