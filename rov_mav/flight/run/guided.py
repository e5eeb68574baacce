"""`rov-mav run --controller ardusub-guided`: no law of ours. The mission's reference (the lead-in included) goes to
ArduSub's own GUIDED mode as SET_POSITION_TARGET_LOCAL_NED (position + velocity + yaw, MAV_FRAME_LOCAL_NED; and the
acceleration, fed forward, on ArduSub 4.7.2 and later, whose Guided_PosVelAccel takes it: an older ArduSub drops such
a target, so it is sent only where AUTOPILOT_VERSION says the vehicle takes it) at a chosen rate of vehicle time, and
ArduSub's position controller flies it on the vehicle's own motor outputs. On an altitude leg the target goes as
SET_POSITION_TARGET_GLOBAL_INT at the leg's height above the terrain (MAV_FRAME_GLOBAL_TERRAIN_ALT_INT): ArduSub
holds it from its own rangefinder (PR #27767; ArduSub 4.7.2 ignores such a target underwater, and a run on it gets
no depth from it: say so in its report).

What the runner changes on the vehicle for it: the mode (GUIDED while flying; back to MANUAL before the stop, and to
the mode it found at the end) and arming; the outputs stay on their motor functions. It keeps holding neutral RC
overrides, as pilot input: ArduSub's pilot-input failsafe (ArduSub/failsafe.cpp, `failsafe_pilot_input_check`:
FS_PILOT_INPUT 2 by default) disarms in every mode after FS_PILOT_TIMEOUT without one, and in GUIDED centred sticks
mean level roll and pitch and no yaw of the pilot's (ArduSub/mode_guided.cpp, `guided_posvel_control_run`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rov_mav.flight.session.link import GUIDED

KIND = "ardusub-guided"
DEFAULT_RATE = 10.0            # Hz of vehicle time
_NAN6 = np.full(6, np.nan)


@dataclass(frozen=True)
class GuidedOutput:
    """A tick's law internals, as a law's ControlOutput has them: none here (NaN), the vehicle computes its own."""

    tau: np.ndarray
    tau_hat: np.ndarray
    s: np.ndarray
    gamma: np.ndarray


class GuidedStream:
    """The reference streamed to GUIDED at `rate` Hz of vehicle time over `session` (a flight.session.link.Session)."""

    mode = GUIDED
    output = GuidedOutput(_NAN6, _NAN6, _NAN6, _NAN6)

    def __init__(self, session, rate: float = DEFAULT_RATE):
        self.session = session
        self.period = 1.0 / rate
        self.rate = rate
        self._next = -math.inf
        self.last: np.ndarray | None = None      # the last reference sent (18,)
        self.sent = 0
        self.accelerations = False               # the vehicle takes acceleration targets (set once it is known)

    def tick(self, t: float, reference: np.ndarray, send: bool, height: float | None = None) -> bool:
        """At vehicle time t: send `reference` (eta_d, eta_dot_d, ...) if one is due, or on an altitude leg
        (`height` m above the bottom) its north and east at that height above the terrain, for ArduSub to hold
        from its own rangefinder; True if it went (or, with send False, would have gone)."""
        if t < self._next:
            return False
        self._next = self._next + self.period if t - self._next < self.period else t + self.period
        self.last = np.array(reference, dtype=float)
        if send:
            if height is not None:
                velocity = np.array([*self.last[6:8], 0.0])
                if not self.session.send_position_target_terrain(self.last[:2], height, velocity):
                    return False
            else:
                self.session.send_position_target(self.last[:3], self.last[6:9], self.last[5],
                                                  self.last[12:15] if self.accelerations else None)
            self.sent += 1
        return True

    def hold(self) -> None:
        """Stop on the last target sent: its position and heading, zero velocity (telemetry stale, or stopping)."""
        if self.last is not None:
            self.session.send_position_target(self.last[:3], np.zeros(3), self.last[5])
