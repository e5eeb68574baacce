"""The vehicle's clock seen from the ground: its timestamps mapped onto the wall clock, a reboot told from a late
packet, and the link's round trip (TIMESYNC).

A vehicle running faster than real time (SITL or the bridge at `--speedup N`) runs every timer N times faster, so
heartbeats, overrides and the watchdog must count vehicle seconds. `VehicleClock` learns the ratio from the
vehicle's own timestamps (time_boot_ms) and extrapolates between them, so that it keeps running when the
vehicle goes silent (which is how a lost link shows).
"""

from __future__ import annotations

import time
from collections import deque

import numpy as np

WINDOW = 1.0            # wall s between re-estimates of the rate
REBOOT_S = 1.0          # a timestamp this far behind the newest is a new boot, not a late or reordered packet
RTT_SAMPLES = 15        # round trips in the median


def is_reboot(newest_s: float, t_s: float) -> bool:
    """Whether a vehicle timestamp `t_s` heard after `newest_s` (s since boot) says the vehicle booted again: its
    clock went back by REBOOT_S or more. The one rule for the clock, the state decoder and the run."""
    return newest_s - t_s >= REBOOT_S


class RoundTrip:
    """The link's round trip from TIMESYNC answers: the median of the last RTT_SAMPLES, vehicle s."""

    def __init__(self):
        self.samples: deque[float] = deque(maxlen=RTT_SAMPLES)

    def add(self, vehicle_seconds: float) -> None:
        if vehicle_seconds >= 0:
            self.samples.append(vehicle_seconds)

    @property
    def seconds(self) -> float:
        return float(np.median(self.samples)) if self.samples else 0.0


class VehicleClock:
    """Estimated vehicle time (s since the vehicle booted) at any wall instant."""

    def __init__(self, rate: float = 1.0, clock=time.perf_counter):
        self.rate = rate               # vehicle seconds per wall second
        self.clock = clock
        self.last_vehicle: float | None = None
        self.last_wall = 0.0
        self._anchor: tuple[float, float] | None = None
        self.reboots: list[tuple[float, float]] = []   # (the last time before, the first after): the clock went back

    def observe(self, vehicle_t: float, wall: float | None = None) -> None:
        """A timestamp `vehicle_t` (s) received at `wall` (default now). Earlier timestamps are ignored."""
        wall = self.clock() if wall is None else wall
        if self.last_vehicle is not None and vehicle_t < self.last_vehicle:
            if not is_reboot(self.last_vehicle, vehicle_t):
                return                      # reordered or late: keep the newest
            self._anchor = None             # the vehicle rebooted
            self.reboots.append((self.last_vehicle, vehicle_t))
        self.last_vehicle, self.last_wall = vehicle_t, wall
        if self._anchor is None:
            self._anchor = (vehicle_t, wall)
        elif wall - self._anchor[1] >= WINDOW:
            self.rate = max((vehicle_t - self._anchor[0]) / (wall - self._anchor[1]), 1e-3)
            self._anchor = (vehicle_t, wall)

    @property
    def started(self) -> bool:
        return self.last_vehicle is not None

    def now(self, wall: float | None = None) -> float:
        """Vehicle time now: the last timestamp advanced at the learned rate (0 before any timestamp)."""
        if self.last_vehicle is None:
            return 0.0
        wall = self.clock() if wall is None else wall
        return self.last_vehicle + (wall - self.last_wall) * self.rate

    def wall_seconds(self, vehicle_seconds: float) -> float:
        """How many wall seconds `vehicle_seconds` take at the learned rate."""
        return vehicle_seconds / self.rate
