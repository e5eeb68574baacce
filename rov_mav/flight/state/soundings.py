"""An echo sounder's readings as the link carries them: DISTANCE_SENSOR from the sounder's own service (BlueOS's Ping
service, component 194, about 10 Hz) or, when none is heard, the autopilot's re-sent copy of its rangefinder
(`GCS_MAVLINK::send_distance_sensor`, EXTRA3, 3 Hz by default), stamped with the vehicle's clock on arrival (the
service stamps its own uptime). Signal quality as MAVLink has it: 0 unknown (taken, as ArduSub takes -1), 1
invalid, else the percentage. Pure: no I/O.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

from pymavlink.dialects.v20 import ardupilotmega as mavlink

DOWN, UP = mavlink.MAV_SENSOR_ROTATION_PITCH_270, mavlink.MAV_SENSOR_ROTATION_PITCH_90   # 25, 24
KEPT = 1000                       # readings kept untaken (a run without altitude legs never takes them)


@dataclass(frozen=True)
class Sounding:
    t: float                      # vehicle s at arrival
    distance: float               # m
    quality: int                  # 0-100 (MAVLink's 0 "unknown" read as 100, 1 "invalid" as 0)
    orientation: int


class Soundings:
    """`update(msg, t)` with every message heard; `take()` the soundings since the last take, in order."""

    def __init__(self, autopilot_component: int = 1):
        self.autopilot_component = autopilot_component
        self.sources: set[tuple[int, int]] = set()
        self._pending: deque[Sounding] = deque(maxlen=KEPT)

    def update(self, msg, t: float) -> None:
        if msg.get_type() != "DISTANCE_SENSOR" or msg.orientation not in (DOWN, UP):
            return
        source = (msg.get_srcSystem(), msg.get_srcComponent())
        self.sources.add(source)
        own = source[1] == self.autopilot_component
        if own and any(component != self.autopilot_component for _, component in self.sources):
            return                # the sounder's own readings are heard: not the autopilot's slower copy
        quality = 100 if msg.signal_quality == 0 else 0 if msg.signal_quality == 1 else int(msg.signal_quality)
        self._pending.append(Sounding(t, msg.current_distance / 100.0, quality, msg.orientation))

    def take(self) -> list[Sounding]:
        out = list(self._pending)
        self._pending.clear()
        return out
