"""Per-link message scheduling on the simulated clock: stream rates, SET_MESSAGE_INTERVAL, REQUEST_DATA_STREAM.

A message's interval is, in order: the one set by MAV_CMD_SET_MESSAGE_INTERVAL on this link, else its stream
group's rate parameter (SRn_* / MAVn_*), else 1 s for HEARTBEAT, else off. As in ArduPilot
(libraries/GCS_MAVLink/GCS_Common.cpp) intervals are whole milliseconds: `set_message_interval` maps the requested
interval (int32 us) 0 to the default, -1 to off, anything else below 1000 to 1 ms and above 60 s to 60 s;
`get_interval_for_stream` maps an int16 rate r to 1000 / r ms (integer division: 0, i.e. off, above 1000 Hz; a
negative rate wraps to a huge unsigned value and so gives 60 s), r = 0 to off.
"""

from __future__ import annotations

import math
from collections.abc import Callable

STREAMS = {
    "RAW_SENS": ("SCALED_PRESSURE2",),
    "EXT_STAT": ("SYS_STATUS", "MISSION_CURRENT", "NAMED_VALUE_FLOAT"),
    "RC_CHAN": ("SERVO_OUTPUT_RAW", "RC_CHANNELS"),
    "POSITION": ("GLOBAL_POSITION_INT", "LOCAL_POSITION_NED"),
    "EXTRA1": ("ATTITUDE",),
    "EXTRA2": ("VFR_HUD",),
    "EXTRA3": ("SYSTEM_TIME", "BATTERY_STATUS", "EKF_STATUS_REPORT", "DISTANCE_SENSOR"),
}
# 4.5 also streamed RANGEFINDER in EXTRA3 (ArduSub/GCS_Mavlink.cpp); 4.7 sends it only when asked (PR #31095)
STREAMS_4_5 = {"RANGEFINDER": "EXTRA3"}
GROUP_OF = {name: group for group, names in STREAMS.items() for name in names}
# MAV_DATA_STREAM ids of REQUEST_DATA_STREAM -> stream groups (0 = all).
DATA_STREAM_GROUPS = {1: ("RAW_SENS",), 2: ("EXT_STAT",), 3: ("RC_CHAN",), 4: ("RAW_CTRL",), 6: ("POSITION",),
                      10: ("EXTRA1",), 11: ("EXTRA2",), 12: ("EXTRA3",)}
HEARTBEAT_INTERVAL = 1.0
MAX_INTERVAL_MS = 60000
EPS = 1e-9                      # s: tolerance for float sums of intervals against step times


class Scheduler:
    """Which of `names` are due on one link; `stream_rate(group)` reads that link's rate parameter in Hz."""

    def __init__(self, names: tuple[str, ...], stream_rate: Callable[[str], float],
                 groups: dict[str, str] | None = None):
        self.names = names
        self.stream_rate = stream_rate
        self.groups = GROUP_OF if groups is None else groups     # message -> its stream group
        self.explicit: dict[str, float] = {}       # name -> interval s (0 = off)
        self.intervals: dict[str, float] = {}
        self._next: dict[str, float] = {}
        self._earliest = 0.0
        self.refresh(0.0)

    def default_interval(self, name: str) -> float:
        """Interval in s from the stream rates (0 = off)."""
        if name == "HEARTBEAT":
            return HEARTBEAT_INTERVAL
        group = self.groups.get(name)
        return stream_interval_ms(int(self.stream_rate(group)) if group else 0) / 1000.0

    def set_interval(self, name: str, interval_us: int, t: float) -> None:
        """MAV_CMD_SET_MESSAGE_INTERVAL's interval (int32 us): 0 = back to the default, -1 = off, else as ArduPilot."""
        ms = requested_interval_ms(interval_us)
        if ms is None:
            self.explicit.pop(name, None)
        else:
            self.explicit[name] = ms / 1000.0
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


def stream_interval_ms(rate: int) -> int:
    """`GCS_MAVLINK::get_interval_for_stream`: the interval (ms, 0 = off) of an int16 stream rate in Hz."""
    if rate == 0:
        return 0
    ms = 1000 // rate if rate > 0 else MAX_INTERVAL_MS + 1
    return min(ms, MAX_INTERVAL_MS)


def requested_interval_ms(interval_us: int) -> int | None:
    """`GCS_MAVLINK::set_message_interval` on an int32 interval in us: the interval in ms (0 = off), None = the
    default."""
    if interval_us == 0:
        return None
    if interval_us == -1:
        return 0
    if interval_us < 1000:
        return 1
    return min(interval_us // 1000, MAX_INTERVAL_MS)
