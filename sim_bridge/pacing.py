"""Pacing a fixed-step simulation against the wall clock at a speedup, and measuring how well it keeps time.

Step k of h seconds is due at wall time anchor + (k h - anchor_sim) / speedup. Its lateness (actual start minus due
time, wall seconds) is recorded; that is the loop jitter. If the loop falls more than `max_lag` wall seconds
behind (an overloaded machine), it re-anchors instead of bursting to catch up, and counts a slip: simulated time
then runs slower than asked, but every step stays h long.
"""

from __future__ import annotations

import time
from array import array

import numpy as np


class Pacer:
    """Wall-clock schedule of a simulation stepping `h` s of simulated time per step, `speedup` x real time."""

    def __init__(self, h: float, speedup: float, max_lag: float = 1.0, clock=time.perf_counter):
        self.h = h
        self.max_lag = max_lag
        self.clock = clock
        self.lateness = array("d")
        self.slips = 0
        self.wall_start = clock()
        self.sim_start = 0.0
        self.speedup = speedup
        self._anchor(0.0)

    def _anchor(self, t: float) -> None:
        self._wall0 = self.clock()
        self._sim0 = t

    def set_speedup(self, speedup: float, t: float) -> None:
        """Change the speedup from sim time t on."""
        if speedup != self.speedup:
            self.speedup = speedup
            self._anchor(t)

    def due(self, t: float) -> bool:
        """Is the step starting at sim time t due now? Records its lateness when it is."""
        late = self.clock() - (self._wall0 + (t - self._sim0) / self.speedup)
        if late < 0:
            return False
        if late > self.max_lag:
            self.slips += 1
            self._anchor(t)
            late = 0.0
        self.lateness.append(late)
        return True

    def wait(self, t: float) -> float:
        """Wall seconds until the step starting at sim time t is due (0 if it already is)."""
        return max(0.0, self._wall0 + (t - self._sim0) / self.speedup - self.clock())

    def summary(self, t: float) -> dict:
        """Achieved speedup and lateness statistics (ms) since the start, at sim time t."""
        wall = self.clock() - self.wall_start
        late = np.frombuffer(self.lateness, dtype=float) * 1e3 if len(self.lateness) else np.zeros(1)
        return {
            "sim_time": t,
            "wall_time": wall,
            "speedup": t / wall if wall > 0 else 0.0,
            "steps": len(self.lateness),
            "slips": self.slips,
            "late_mean_ms": float(late.mean()),
            "late_p50_ms": float(np.percentile(late, 50)),
            "late_p99_ms": float(np.percentile(late, 99)),
            "late_max_ms": float(late.max()),
        }
