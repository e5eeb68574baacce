"""RC input of a vehicle with no RC receiver (a real BlueROV2): 18 channels fed only by GCS overrides.

ArduPilot semantics, on the simulated clock: an override holds a channel until it is released or RC_OVERRIDE_TIME
(s) passes (-1: never; 0: overrides disabled). With no receiver behind it, a channel whose override ends KEEPS ITS
LAST VALUE (the passthrough hazard), so `radio_in` is only ever written, never reset, by expiry.
"""

from __future__ import annotations

import numpy as np

CHANNELS = 18
UINT16_MAX = 65535


class RCInput:
    """Channel values `radio_in` (18,) in us and their overrides; channel numbers here are 0-based."""

    def __init__(self):
        self.radio_in = np.zeros(CHANNELS, dtype=np.int32)
        self.radio_in[:8] = 1500          # ArduSub starts its pilot and camera channels at neutral
        self.radio_in[8:11] = 1100        # lights and video switch start low
        self._override = np.zeros(CHANNELS, dtype=np.int32)
        self._stamp = np.full(CHANNELS, -np.inf)   # sim time of each override, -inf = none

    def set_override(self, channel: int, value: int, t: float) -> None:
        """Override `channel` with `value` us from time `t`; value 0 releases it."""
        if value == 0:
            self._stamp[channel] = -np.inf
        else:
            self._override[channel] = value
            self._stamp[channel] = t

    def apply_message(self, values: list[int], t: float) -> None:
        """RC_CHANNELS_OVERRIDE's 18 fields: on 1-8 UINT16_MAX ignores and 0 releases; on 9-18 0 and UINT16_MAX
        ignore and UINT16_MAX-1 releases."""
        for ch, value in enumerate(values[:CHANNELS]):
            if ch < 8:
                if value != UINT16_MAX:
                    self.set_override(ch, value, t)
            elif value not in (0, UINT16_MAX):
                self.set_override(ch, 0 if value == UINT16_MAX - 1 else value, t)

    def update(self, t: float, override_time: float) -> None:
        """Copy live overrides into `radio_in`; expired or released channels keep their last value."""
        if override_time == 0:
            return
        if override_time < 0:
            live = self._stamp > -np.inf
        else:
            live = (t - self._stamp) < override_time
        self.radio_in[live] = self._override[live]

    def norm_input(self, channel: int, low: float, trim: float, high: float) -> float:
        """ArduPilot's norm_input: (radio_in - trim) scaled by the side's span, clamped to [-1, 1]."""
        value = float(self.radio_in[channel])
        span = (trim - low) if value < trim else (high - trim)
        if span <= 0:
            return 0.0
        return min(max((value - trim) / span, -1.0), 1.0)
