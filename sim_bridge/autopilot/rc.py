"""RC input of a vehicle with no RC receiver (a real BlueROV2): 16 channels fed only by GCS overrides.

ArduPilot semantics, on the simulated clock: an override holds a channel until it is released or RC_OVERRIDE_TIME
(s) passes (-1: never; 0: overrides disabled). With no receiver behind it, a channel whose override ends KEEPS ITS
LAST VALUE (the passthrough hazard), so `radio_in` is only ever written, never reset, by expiry.

Widths as in libraries/RC_Channel: an override is a uint16_t (`RC_Channel::set_override`), `radio_in` an int16_t,
so an override of 32768..65534 reads as a negative pulse in `norm_input` (measured on ArduSub 4.5.3 SITL: 40000 on
the throttle channel drove the vertical thrusters full down) while RC_CHANNELS and RCIN passthrough, which take it
back as uint16_t, show it unchanged. RC_CHANNELS_OVERRIDE's channels 17 and 18 are ignored (NUM_RC_CHANNELS is 16).
"""

from __future__ import annotations

import numpy as np

from sim_bridge.hardware.numeric import wrap

CHANNELS = 16
UINT16_MAX = 65535


class RCInput:
    """Channel values `radio_in` (16,) in us and their overrides; channel numbers here are 0-based."""

    def __init__(self, firmware: str = "4.7"):
        self.radio_in = np.zeros(CHANNELS, dtype=np.int32)          # as uint16: what RC_CHANNELS reports
        self.radio_in[:8] = 1500          # ArduSub starts its pilot and camera channels at neutral (`Sub::init_rc_in`)
        if firmware == "4.5":
            self.radio_in[8:11] = 1100    # 4.5: lights and video switch start low; 4.7: never written, they read 0
        self._override = np.zeros(CHANNELS, dtype=np.int32)
        self._stamp = np.full(CHANNELS, -np.inf)   # sim time of each override, -inf = none

    def set_override(self, channel: int, value: int, t: float) -> None:
        """Override `channel` with `value` us (as a uint16) from time `t`; value 0 releases it."""
        value = wrap(int(value), 16, signed=False)
        if value == 0:
            self._stamp[channel] = -np.inf
        else:
            self._override[channel] = value
            self._stamp[channel] = t

    def apply_message(self, values: list[int], t: float) -> None:
        """RC_CHANNELS_OVERRIDE's channel fields (GCS_Common.cpp, `handle_rc_channels_override`): on 1-8 UINT16_MAX
        ignores and 0 releases; on 9-16 0 and UINT16_MAX ignore and UINT16_MAX-1 releases; 17-18 are ignored."""
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
        """ArduPilot's `RC_Channel::norm_input`: (radio_in - trim) scaled by the side's span, clamped to [-1, 1]."""
        value = float(wrap(int(self.radio_in[channel]), 16))          # radio_in is an int16_t
        span = (trim - low) if value < trim else (high - trim)
        if span <= 0:
            return 0.0
        return min(max((value - trim) / span, -1.0), 1.0)
