"""Per-link message scheduling on the simulated clock: stream rates, SET_MESSAGE_INTERVAL, REQUEST_DATA_STREAM.

A message's interval is, in order: the one set by MAV_CMD_SET_MESSAGE_INTERVAL on this link (-1 there = off), else
1 / its stream group's rate parameter (SRn_* / MAVn_*), else 1 s for HEARTBEAT, else off.
"""

from __future__ import annotations

import math
from collections.abc import Callable

STREAMS = {
    "RAW_SENS": ("SCALED_PRESSURE2",),
    "EXT_STAT": ("SYS_STATUS",),
    "RC_CHAN": ("SERVO_OUTPUT_RAW", "RC_CHANNELS"),
    "POSITION": ("GLOBAL_POSITION_INT", "LOCAL_POSITION_NED"),
    "EXTRA1": ("ATTITUDE",),
    "EXTRA2": ("VFR_HUD",),
    "EXTRA3": ("SYSTEM_TIME", "BATTERY_STATUS"),
}
GROUP_OF = {name: group for group, names in STREAMS.items() for name in names}
# MAV_DATA_STREAM ids of REQUEST_DATA_STREAM -> stream groups (0 = all).
DATA_STREAM_GROUPS = {1: ("RAW_SENS",), 2: ("EXT_STAT",), 3: ("RC_CHAN",), 4: ("RAW_CTRL",), 6: ("POSITION",),
                      10: ("EXTRA1",), 11: ("EXTRA2",), 12: ("EXTRA3",)}
HEARTBEAT_INTERVAL = 1.0
EPS = 1e-9                      # s: tolerance for float sums of intervals against step times


class Scheduler:
    """Which of `names` are due on one link; `stream_rate(group)` reads that link's rate parameter in Hz."""

    def __init__(self, names: tuple[str, ...], stream_rate: Callable[[str], float]):
        self.names = names
        self.stream_rate = stream_rate
        self.explicit: dict[str, float] = {}       # name -> interval s (0 = off)
        self.intervals: dict[str, float] = {}
        self._next: dict[str, float] = {}
        self._earliest = 0.0
        self.refresh(0.0)

    def default_interval(self, name: str) -> float:
        """Interval in s from the stream rates (0 = off)."""
        if name == "HEARTBEAT":
            return HEARTBEAT_INTERVAL
        group = GROUP_OF.get(name)
        rate = self.stream_rate(group) if group else 0.0
        return 1.0 / rate if rate > 0 else 0.0

    def set_interval(self, name: str, interval_us: float, t: float) -> None:
        """MAV_CMD_SET_MESSAGE_INTERVAL: 0 = back to the default, < 0 = off, else the interval in us."""
        if interval_us == 0:
            self.explicit.pop(name, None)
        else:
            self.explicit[name] = 0.0 if interval_us < 0 else interval_us * 1e-6
        self.refresh(t)

    def refresh(self, t: float) -> None:
        """Recompute every interval (after a rate parameter or interval changed); changed ones restart at t."""
        for name in self.names:
            interval = self.explicit.get(name, self.default_interval(name))
            if interval != self.intervals.get(name):
                self.intervals[name] = interval
                self._next[name] = t if interval > 0 else math.inf
        self._earliest = min(self._next.values())

    def due(self, t: float) -> list[str]:
        """Names due at time t, each rescheduled one interval on (without piling up when late)."""
        if t < self._earliest - EPS:
            return []
        out = []
        for name, when in self._next.items():
            if t >= when - EPS:
                out.append(name)
                interval = self.intervals[name]
                nxt = when + interval
                self._next[name] = nxt if nxt > t + EPS else t + interval
        self._earliest = min(self._next.values())
        return out
