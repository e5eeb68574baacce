"""The runner's state prediction: the vehicle's late state carried forward to the instant its next command acts.

A state sampled on the vehicle at t_s reaches us a downlink delay later; the command computed from it reaches the
thrusters an uplink delay after it leaves. The law should act on the state at that instant, not at t_s. The horizon
is measured, not assumed: `clock.now() - t_s` (how much older this state is than the newest timestamp heard, plus our
own processing) plus the round trip (TIMESYNC, as ArduPilot answers it: `GCS_MAVLINK::handle_timesync` in
libraries/GCS_MAVLink/GCS_Common.cpp echoes our ts1 at once), since our clock of the vehicle lags it by the downlink
delay. The state is carried over the horizon by the offline loop's own compiled predictor (`kernel.predict`: the
controller's model under the wrenches already commanded, each from the instant it acts, plus a disturbance learnt
from every new sample, `kernel.observe_disturbance`), so a run and `simulate` predict alike.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from rov_mav.model import kernel

MAX_HORIZON = 2.0        # vehicle s: the furthest a state is predicted (the run stops rather than act on an older one)
CAPACITY = 2048          # commands held (compacted to the newest half when full: over MAX_HORIZON at 400 Hz)
RTT_SAMPLES = 15         # round trips in the median


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


class StatePredictor:
    """`commanded(t_act, wrench)` for every command sent; `predicted(t, eta, nu, t_act)` -> (eta, nu) at t_act."""

    def __init__(self, model_packed: np.ndarray, slot: float):
        self.model = np.ascontiguousarray(model_packed, dtype=float)
        self.slot = slot                                       # vehicle s: the ring's resolution (a control period)
        self._times = np.zeros(CAPACITY)                       # vehicle s each command acts from, ascending
        self._wrenches = np.zeros((CAPACITY, 6))
        self._count = 0
        self.d_hat = np.zeros(6)
        self._previous: tuple[float, np.ndarray] | None = None    # the last state observed: (t, x)
        self._ws = np.zeros(72)
        self._out = np.zeros(12)

    def commanded(self, t_act: float, wrench: np.ndarray) -> None:
        """A wrench that acts on the vehicle from vehicle time t_act (until the next one)."""
        if self._count == CAPACITY:
            half = CAPACITY // 2
            self._times[:half] = self._times[half:]
            self._wrenches[:half] = self._wrenches[half:]
            self._count = half
        self._times[self._count] = t_act
        self._wrenches[self._count] = wrench
        self._count += 1

    def reset(self) -> None:
        """Forget the disturbance learnt and the last state (after a gap the model cannot bridge)."""
        self.d_hat[:] = 0.0
        self._previous = None

    def observe(self, t: float, eta: np.ndarray, nu: np.ndarray) -> None:
        """A new measured state at vehicle time t: learn what the model missed since the previous one."""
        x = np.concatenate([eta, nu])
        if self._previous is not None and 0.0 < t - self._previous[0] <= MAX_HORIZON:
            t0, x0 = self._previous
            ring = self._ring(t, t - t0)
            kernel.observe_disturbance(self.model, x0, kernel.attitude_trig(x0), ring, len(ring) - 1, self.slot,
                                       t - t0, x, self.d_hat, self._ws)
        self._previous = (t, x)

    def predicted(self, t: float, eta: np.ndarray, nu: np.ndarray, t_act: float) -> tuple[np.ndarray, np.ndarray]:
        """The state measured at t carried forward to t_act (as it is when t_act <= t or too far ahead)."""
        horizon = t_act - t
        if horizon <= 0.0 or horizon > MAX_HORIZON:
            return eta, nu
        x = np.concatenate([eta, nu])
        ring = self._ring(t_act, horizon)
        kernel.predict(self.model, x, kernel.attitude_trig(x), ring, len(ring) - 1, self.slot, horizon, self.d_hat,
                       self._out, self._ws[:60])
        return self._out[:6].copy(), self._out[6:].copy()

    def _ring(self, end: float, span: float) -> np.ndarray:
        """The commanded wrench per slot over the `span` s before `end` (oldest first, newest last, a slot more for
        rounding): each slot the mean of the wrenches acting over it (zero before the first command), so that the
        prediction integrates every command from the instant it acts, whatever the slots' alignment."""
        n = int(np.ceil(span / self.slot)) + 1
        edges = end - np.arange(n, -1, -1) * self.slot
        times, wrenches = self._times[:self._count], self._wrenches[:self._count]
        first = max(int(np.searchsorted(times, edges[0], side="right")) - 1, 0)   # the command acting at the start
        times, wrenches = times[first:], wrenches[first:]
        if times.size == 0:
            return np.zeros((n, 6))
        # the wrench's integral from the first command kept, at each switch, then at each slot's edge
        at_switch = np.zeros((times.size, 6))
        np.cumsum(wrenches[:-1] * np.diff(times)[:, None], axis=0, out=at_switch[1:])
        index = np.searchsorted(times, edges, side="right") - 1
        since = np.maximum(index, 0)
        integral = at_switch[since] + wrenches[since] * (edges - times[since])[:, None]
        integral[index < 0] = 0.0
        return np.diff(integral, axis=0) / self.slot

