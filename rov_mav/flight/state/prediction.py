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

import numpy as np

from rov_mav.model import kernel

MAX_HORIZON = 2.0        # vehicle s: the furthest a state is predicted (the run stops rather than act on an older one)
CAPACITY = 2048          # commands held (compacted to the newest half when full: over MAX_HORIZON at 400 Hz)


class CommandHistory:
    """Commands (k values each) with the vehicle time each acts from, held until the next: `add(t_act, values)`,
    `slot_means(end, span, slot)`."""

    def __init__(self, size: int):
        self._times = np.zeros(CAPACITY)                       # vehicle s each command acts from, ascending
        self._values = np.zeros((CAPACITY, size))
        self._count = 0

    def add(self, t_act: float, values: np.ndarray) -> None:
        """`values` act from t_act on. Commands stamped at or after t_act are dropped: our clock of the vehicle ran
        ahead of it (the vehicle or its link stalled, then the clock was set back by its next sample), so they were
        stamped later than they acted, and the newest command is what acts from t_act (the times stay ascending)."""
        if self._count and self._times[self._count - 1] >= t_act:
            self._count = int(np.searchsorted(self._times[:self._count], t_act, side="left"))
        if self._count == CAPACITY:
            half = CAPACITY // 2
            self._times[:half] = self._times[half:]
            self._values[:half] = self._values[half:]
            self._count = half
        self._times[self._count] = t_act
        self._values[self._count] = values
        self._count += 1

    def slot_means(self, end: float, span: float, slot: float) -> np.ndarray:
        """The command per slot over the `span` s before `end` (oldest first, newest last, a slot more for
        rounding): each slot the mean of the commands acting over it (zero before the first), so that a prediction
        integrates every command from the instant it acts, whatever the slots' alignment."""
        n = int(np.ceil(span / slot)) + 1
        edges = end - np.arange(n, -1, -1) * slot
        times, values = self._times[:self._count], self._values[:self._count]
        first = max(int(np.searchsorted(times, edges[0], side="right")) - 1, 0)   # the command acting at the start
        times, values = times[first:], values[first:]
        if times.size == 0:
            return np.zeros((n, values.shape[1]))
        # the command's integral from the first one kept, at each switch, then at each slot's edge
        at_switch = np.zeros((times.size, values.shape[1]))
        np.cumsum(values[:-1] * np.diff(times)[:, None], axis=0, out=at_switch[1:])
        index = np.searchsorted(times, edges, side="right") - 1
        since = np.maximum(index, 0)
        integral = at_switch[since] + values[since] * (edges - times[since])[:, None]
        integral[index < 0] = 0.0
        return np.diff(integral, axis=0) / slot


class StatePredictor:
    """`commanded(t_act, wrench)` for every command sent; `predicted(t, eta, nu, t_act)` -> (eta, nu) at t_act."""

    def __init__(self, model_packed: np.ndarray, slot: float):
        self.model = np.ascontiguousarray(model_packed, dtype=float)
        self.slot = slot                                       # vehicle s: the ring's resolution (a control period)
        self.wrenches = CommandHistory(6)
        self.d_hat = np.zeros(6)
        self._previous: tuple[float, np.ndarray] | None = None    # the last state observed: (t, x)
        self._ws = np.zeros(72)
        self._out = np.zeros(12)

    def commanded(self, t_act: float, wrench: np.ndarray) -> None:
        """A wrench that acts on the vehicle from vehicle time t_act (until the next one)."""
        self.wrenches.add(t_act, wrench)

    def observe(self, t: float, eta: np.ndarray, nu: np.ndarray) -> None:
        """A new measured state at vehicle time t: learn what the model missed since the previous one."""
        x = np.concatenate([eta, nu])
        if self._previous is not None and 0.0 < t - self._previous[0] <= MAX_HORIZON:
            t0, x0 = self._previous
            ring = self.wrenches.slot_means(t, t - t0, self.slot)
            kernel.observe_disturbance(self.model, x0, kernel.attitude_trig(x0), ring, len(ring) - 1, self.slot,
                                       t - t0, x, self.d_hat, self._ws)
        self._previous = (t, x)

    def predicted(self, t: float, eta: np.ndarray, nu: np.ndarray, t_act: float) -> tuple[np.ndarray, np.ndarray]:
        """The state measured at t carried forward to t_act (as it is when t_act <= t or too far ahead)."""
        horizon = t_act - t
        if horizon <= 0.0 or horizon > MAX_HORIZON:
            return eta, nu
        x = np.concatenate([eta, nu])
        ring = self.wrenches.slot_means(t_act, horizon, self.slot)
        kernel.predict(self.model, x, kernel.attitude_trig(x), ring, len(ring) - 1, self.slot, horizon, self.d_hat,
                       self._out, self._ws[:60])
        return self._out[:6].copy(), self._out[6:].copy()
