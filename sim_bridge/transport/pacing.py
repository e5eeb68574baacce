"""Pacing a fixed-step simulation against the wall clock at a speedup, and measuring how well it keeps time.

Step k of h seconds is due at wall time anchor + (k h - anchor_sim) / speedup. Its lateness (actual start minus due
time, wall seconds) is recorded in a fixed-size histogram (memory stays flat however long the bridge runs); that is the
loop jitter. If the loop falls more than `catch_up` simulated seconds behind (an overloaded machine, a stopped
process), it re-anchors instead of bursting to catch up, and counts a slip: simulated time then runs slower than
asked, but every step stays h long. ArduPilot's SITL lets at most 100 ms of wall time build up as sleep debt
(`Aircraft::sync_frame_time`, libraries/SITL/SIM_Aircraft.cpp), which at 1x is 0.1 s of the vehicle's; the pacer
keeps that 0.1 s of the vehicle's at every speedup: a longer stall pauses the world with its autopilot. Bursting
through it instead runs seconds of the vehicle's water in a few wall milliseconds, faster than any station on the
link can answer, which no real dive does (a run at --rate 5 tipped past max_tilt after such a burst).
"""

from __future__ import annotations

import math
import time

import numpy as np

BINS_PER_DECADE = 100                 # percentiles to within 2.3 % of their value
SMALLEST, LARGEST = 1e-7, 100.0       # s: lateness below counts in the first bin, above in the last
CATCH_UP = 0.1                        # simulated s behind the schedule caught up in a burst; more is a slip


class LatenessHistogram:
    """Count, mean, max and log-binned percentiles of non-negative lateness values, in constant memory."""

    def __init__(self):
        decades = math.log10(LARGEST / SMALLEST)
        self.edges = SMALLEST * 10.0 ** (np.arange(int(decades * BINS_PER_DECADE) + 1) / BINS_PER_DECADE)
        self.counts = np.zeros(self.edges.size + 1, dtype=np.int64)   # [0, e0), [e0, e1), ..., [e_last, inf)
        self.count = 0
        self.total = 0.0
        self.max = 0.0
        self.last = 0.0

    def add(self, late: float) -> None:
        self.counts[int(np.searchsorted(self.edges, late, side="right"))] += 1
        self.count += 1
        self.total += late
        self.max = max(self.max, late)
        self.last = late

    def percentile(self, q: float) -> float:
        """The q-th percentile (0-100): the geometric centre of the bin holding it (0 below the first edge)."""
        if not self.count:
            return 0.0
        k = int(np.searchsorted(np.cumsum(self.counts), math.ceil(q / 100.0 * self.count)))
        if k == 0:
            return 0.0
        if k >= self.edges.size:
            return self.max
        return min(math.sqrt(self.edges[k - 1] * self.edges[k]), self.max)


class Pacer:
    """Wall-clock schedule of a simulation stepping `h` s of simulated time per step, `speedup` x real time."""

    def __init__(self, h: float, speedup: float, catch_up: float = CATCH_UP, clock=time.perf_counter):
        self.h = h
        self.catch_up = catch_up
        self.clock = clock
        self.lateness = LatenessHistogram()
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
        if late * self.speedup > self.catch_up:
            self.slips += 1
            self._anchor(t)
            late = 0.0
        self.lateness.add(late)
        return True

    def wait(self, t: float) -> float:
        """Wall seconds until the step starting at sim time t is due (0 if it already is)."""
        return max(0.0, self._wall0 + (t - self._sim0) / self.speedup - self.clock())

    def summary(self, t: float) -> dict:
        """Achieved speedup and lateness statistics (ms) since the start, at sim time t."""
        wall = self.clock() - self.wall_start
        late = self.lateness
        return {
            "sim_time": t,
            "wall_time": wall,
            "speedup": t / wall if wall > 0 else 0.0,
            "steps": late.count,
            "slips": self.slips,
            "late_mean_ms": 1e3 * late.total / late.count if late.count else 0.0,
            "late_p50_ms": 1e3 * late.percentile(50),
            "late_p99_ms": 1e3 * late.percentile(99),
            "late_max_ms": 1e3 * late.max,
        }
