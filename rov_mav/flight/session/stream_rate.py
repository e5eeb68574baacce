"""How fast the vehicle sends a telemetry stream, and how much of it arrives, from the vehicle's own timestamps.

Over a lossy link the received rate understates what the vehicle sends: the intervals between received messages are
whole multiples of the send period, and while less than 90 % is lost their 10th percentile is one period. So the send
rate is 1 / that percentile and the arriving rate is the count over the span; a duplicate or a reordered message (a
timestamp already seen) counts once. A stream is too slow for the control loop when the
vehicle sends too slowly (it cannot keep up: lower the rate), or when too little of it arrives (the link).
Pure: no I/O; times are vehicle seconds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

SENT_TOLERANCE = 0.8          # fraction of the asked rate the vehicle must send
ARRIVING_TOLERANCE = 0.5      # fraction of the asked rate that must arrive (30 % loss arrives at 70 %)
PERIOD_PERCENTILE = 10        # of the intervals between received messages: one send period below 90 % loss


@dataclass(frozen=True)
class StreamRate:
    sent_hz: float
    arriving_hz: float

    @property
    def lost(self) -> float:
        """Fraction of what was sent that did not arrive."""
        return max(0.0, 1.0 - self.arriving_hz / self.sent_hz) if self.sent_hz > 0 else 1.0

    def describe(self) -> str:
        return f"{self.sent_hz:.1f} Hz sent, {self.arriving_hz:.1f} Hz arriving ({self.lost:.0%} lost)"


def measure(stamps) -> StreamRate:
    """The rates of a stream from the timestamps (vehicle s) of the messages received, in any order."""
    t = np.unique(np.asarray(stamps, dtype=float))
    if t.size < 3 or t[-1] <= t[0]:
        return StreamRate(0.0, 0.0)
    period = np.percentile(np.diff(t), PERIOD_PERCENTILE)
    return StreamRate(float(1.0 / period), float((t.size - 1) / (t[-1] - t[0])))


def too_slow(name: str, rate: StreamRate, asked: float) -> str | None:
    """Why the stream `name` cannot feed a loop at `asked` Hz (one phrase), or None if it can."""
    if rate.sent_hz < SENT_TOLERANCE * asked:
        return (f"the vehicle sends {name} at {rate.sent_hz:.1f} Hz, < {SENT_TOLERANCE:.0%} of {asked:g} Hz "
                "(lower --rate)")
    if rate.arriving_hz < ARRIVING_TOLERANCE * asked:
        return (f"{name} arrives at {rate.arriving_hz:.1f} Hz ({rate.lost:.0%} of it lost), < "
                f"{ARRIVING_TOLERANCE:.0%} of {asked:g} Hz (check the link)")
    return None
