"""A lead-in from wherever the vehicle is to the mission's start pose, so a mission never begins with a jump.

Built as a mission of its own (a goto at a gentle speed, then a short hold to settle) with the mission module's
smooth segments; skipped when the vehicle already sits at the start.
"""

from __future__ import annotations

import math

import numpy as np

from rov_mav import config
from rov_mav.mission.missions import Mission, _MissionSchema
from rov_mav.units import wrap_angle

AT_START_DISTANCE = 0.05          # m
AT_START_HEADING = math.radians(3.0)
TURN_RATE = 0.2                   # rad/s for a turn on the spot
SETTLE = 3.0                      # s of hold at the start pose



def approach(eta: np.ndarray, start: np.ndarray, speed: float) -> Mission | None:
    """The lead-in from pose eta (6,) to the start pose (6,) at `speed` m/s, or None if already there."""
    distance = float(np.linalg.norm(start[:3] - eta[:3]))
    turn = abs(wrap_angle(start[5] - eta[5]))
    if distance < AT_START_DISTANCE and turn < AT_START_HEADING:
        return None
    heading = float(wrap_angle(start[5]))
    path = [{"hold": max(SETTLE, turn / TURN_RATE), "heading": heading}]
    if distance >= AT_START_DISTANCE:
        speed = min(speed, distance * TURN_RATE / turn) if turn > 0 else speed   # no faster turn than on the spot
        path = [{"goto": [float(v) for v in start[:3]], "speed": float(speed), "heading": heading},
                {"hold": SETTLE}]
    data = {"name": "approach", "start": {"position": [float(v) for v in eta[:3]], "heading": wrap_angle(float(eta[5]))},
            "path": path}
    return Mission(config.parse(_MissionSchema, data, "approach"), "approach")
