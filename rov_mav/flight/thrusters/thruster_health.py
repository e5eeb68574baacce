"""Which thrusters do what they are told, from the vehicle's motion alone: a standard BlueROV2 reports no thruster RPM
or current, so a fouled, jammed or miswired thruster shows only as motion the commands do not explain.

Every SPAN s or more of measured states (x_k at vehicle time t_k), the controller's model carries the state of the
span's start, x_{k-1}, over the interval D = t_k - t_{k-1} under the wrench the thrusters were told to give (each
command from the instant it acts, through the thrusters' first-order lag, `kernel.predict`, no disturbance); what the
measured velocity differs by is a wrench, the interval's mean:
    r_k = M (nu_k - nu_model) / D
(over a span of several samples the velocity noise counts once, not once a sample). If thruster i gives (1 + a_i)
times the thrust f_i it is told (a_i = 0 healthy, -1 dead, -0.7 at a third of its thrust, -2 reversed) and the water
pushes with d,
    r_k = a_i B_i fbar_i + d + noise,       fbar_i the mean thrust told to thruster i over the interval,
B_i the allocation matrix's column i. Thrusters fail one at a time, so this is a bank of hypotheses, each a Kalman
filter: "all healthy" (d alone, a random walk: it drifts with waves, current and heading) and, for each thruster,
"thruster i is off by a_i" (d and a_i). Each filter scores how well it predicted every residual (the log-likelihood of
its innovations, forgetting over MEMORY s): a filter with a thruster's a_i free fits at least as well, but pays for
its wider prediction, so it wins only when the motion needs it. A thruster is named when its hypothesis beats "all
healthy" by EVIDENCE and every other thruster's by MARGIN, with its effectiveness 1 + a_i below HEALTHY, for CONFIRM
vehicle s: `Verdict` says dead (or stuck: a steady push the commands do not move), weak (its share) or reversed.
The noise of r is learnt from the best filter's innovations. Pure: no I/O.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rov_mav.flight.state.prediction import MAX_HORIZON, CommandHistory
from rov_mav.model import kernel

HEALTHY = 0.6             # effectiveness below this is a fault
EVIDENCE = 10.0           # nats: how much better a thruster's hypothesis must predict the motion than "all healthy"
MARGIN = 4.0              # nats: ... and than any other thruster's
AGAIN = 3.0               # each fault already answered multiplies both: thrusters fail one at a time, and the first
                          # leaves transients and a push (a stuck one's) that another hypothesis can partly explain
CONFIRM = 0.8             # vehicle s the verdict must hold before it is given
CONFIRM_REVERSED = 0.3    # ... for a thruster pushing the wrong way (the loop through it diverges within a second)
MEMORY = 3.0              # vehicle s over which the scores forget
WARM_UP = 10.0            # vehicle s of samples before any verdict (the disturbance and the noise are learnt first)
SETTLE = 8.0              # vehicle s after a fault is answered before the next verdict (the transient settles)
SPAN = 0.25               # vehicle s: each residual spans at least this (the velocity noise over it, not over a sample)
DEAD = 0.2                # effectiveness below this (and above REVERSED): gives nothing useful
REVERSED = -0.3           # effectiveness below this: pushes the other way
SPREAD_A = 1.0            # std of a_i under its hypothesis (dead is -1, reversed -2)
DRIFT_A = 0.3             # per sqrt(s): a_i's random walk (it steps when the thruster fails)
PRIOR_D = 30.0            # N or N m: std of the disturbance at the start
DRIFT_D = 1.0             # N per sqrt(s) of the random walk of d
NOISE_TIME = 5.0          # s: time constant of the learnt residual noise
NOISE_FLOOR = 1e-4        # N^2: the least residual variance (a noise-free simulation is not infinitely certain)
NOISE_START = 1.0         # N^2: residual variance before any is learnt
STUCK_PUSH = 3.0          # N: a steady push along a dead thruster's axis beyond this names it stuck


@dataclass(frozen=True)
class Verdict:
    """Thruster `thruster` (1-based) gives `effectiveness` of what it is told; `kind` dead | stuck | weak |
    reversed; `push` N: for a stuck one, the steady thrust it gives whatever it is told; `at` the vehicle time the
    estimate first left the healthy range."""

    thruster: int
    kind: str
    effectiveness: float
    at: float
    push: float = 0.0

    def describe(self) -> str:
        if self.kind == "weak":
            return f"thruster {self.thruster} weak: it gives {self.effectiveness:.0%} of the thrust it is told"
        if self.kind == "reversed":
            return f"thruster {self.thruster} reversed: it pushes the other way (effectiveness {self.effectiveness:.2f})"
        if self.kind == "stuck":
            return f"thruster {self.thruster} stuck: a steady {self.push:+.1f} N whatever it is told"
        return f"thruster {self.thruster} dead: no thrust from it (effectiveness {self.effectiveness:.2f})"

    @property
    def gain(self) -> float:
        """The effectiveness to allocate with: 0 for a dead or stuck thruster, else the estimate (-1 reversed)."""
        if self.kind in ("dead", "stuck"):
            return 0.0
        return -1.0 if self.kind == "reversed" else self.effectiveness


class _Hypothesis:
    """One filter of the bank: the disturbance d (6,) and, for a thruster's hypothesis, its a_i first."""

    def __init__(self, thruster: int | None):
        self.thruster = thruster
        self.k = 0 if thruster is None else 1
        self.x = np.zeros(self.k + 6)
        self.P = np.diag([SPREAD_A ** 2] * self.k + [PRIOR_D ** 2] * 6)
        self.score = 0.0
        self.innovation = np.zeros(6)

    @property
    def a(self) -> float:
        return float(self.x[0]) if self.k else 0.0

    @property
    def d(self) -> np.ndarray:
        return self.x[self.k:].copy()

    def restart(self) -> None:
        """After a fault was answered: a_i back to its prior, the disturbance open to learning, no score."""
        if self.k:
            self.x[0] = 0.0
            self.P[0, :] = self.P[:, 0] = 0.0
            self.P[0, 0] = SPREAD_A ** 2
        self.P[self.k:, self.k:] += np.eye(6) * PRIOR_D ** 2
        self.score = 0.0

    def step(self, r: np.ndarray, column: np.ndarray | None, noise: np.ndarray, span: float, keep: float) -> None:
        """One residual r (6,); column = B_i fbar_i for a thruster's hypothesis."""
        k = self.k
        self.P[k:, k:] += np.eye(6) * DRIFT_D ** 2 * span
        if k:
            self.P[0, 0] += DRIFT_A ** 2 * span
        H = np.eye(6) if not k else np.hstack([column[:, None], np.eye(6)])
        self.innovation = r - H @ self.x
        S = H @ self.P @ H.T + np.diag(noise)
        solved = np.linalg.solve(S, np.hstack([self.innovation[:, None], H @ self.P]))
        _, logdet = np.linalg.slogdet(S)
        self.score = keep * self.score - 0.5 * (self.innovation @ solved[:, 0] + logdet)
        gain = solved[:, 1:].T
        self.x += gain @ self.innovation
        self.P -= gain @ H @ self.P
        self.P = 0.5 * (self.P + self.P.T)


class ThrusterHealth:
    """`told(t_act, thrusts)` for every command, `observe(t, x)` for every new measured state; `verdicts(t)` the
    thrusters newly found faulty. `matrix` B (6, n); `model_packed` the controller's model; `slot` s; the thrusters'
    first-order lag `time_constant` s."""

    def __init__(self, model_packed: np.ndarray, matrix: np.ndarray, slot: float, time_constant: float = 0.0):
        self.model = np.ascontiguousarray(model_packed, dtype=float)
        self.matrix = np.asarray(matrix, dtype=float)
        self.n = self.matrix.shape[1]
        self.slot = slot
        self.lag = 1.0 - np.exp(-slot / time_constant) if time_constant > 0 else 1.0   # per slot
        self.settle = 5.0 * time_constant        # s of commands before a span that set its lagged thrust
        self.mass = self.model[kernel.P_M:kernel.P_M + 36].reshape(6, 6)
        self.thrusts = CommandHistory(self.n)
        self.healthy = _Hypothesis(None)
        self.faulty = [_Hypothesis(i) for i in range(self.n)]
        self.noise = np.full(6, NOISE_START)
        self.known = np.ones(self.n)            # the effectiveness allocated with (faults already answered)
        self.excluded = np.zeros(self.n, dtype=bool)
        self._previous: tuple[float, np.ndarray] | None = None
        self._first: float | None = None
        self._quiet_until = -np.inf
        self._since: tuple[int, float] | None = None     # (thruster, vehicle s) of the standing candidate
        self._d_history: list[tuple[float, np.ndarray]] = []
        self._ws = np.zeros(60)
        self._out = np.zeros(12)
        self.residual = np.zeros(6)

    @property
    def effectiveness(self) -> np.ndarray:
        """(n,) each thruster's effectiveness under its own hypothesis (1 healthy), relative to what is allocated."""
        return 1.0 + np.array([h.a for h in self.faulty])

    @property
    def evidence(self) -> np.ndarray:
        """(n,) nats by which each thruster's hypothesis predicts the motion better than "all healthy"."""
        return np.array([h.score - self.healthy.score for h in self.faulty])

    @property
    def disturbance(self) -> np.ndarray:
        """The disturbance as "all healthy" estimates it."""
        return self.healthy.d

    def told(self, t_act: float, thrusts: np.ndarray) -> None:
        """Thrusts (n,) N the thrusters are told to give from vehicle time t_act (what each is expected to give:
        scaled by the effectiveness it is allocated with)."""
        self.thrusts.add(t_act, np.asarray(thrusts, dtype=float) * self.known)

    def observe(self, t: float, x: np.ndarray) -> None:
        """A new measured state x (12,) at vehicle time t."""
        x = np.asarray(x, dtype=float)
        if self._first is None:
            self._first = t
        previous = self._previous
        if previous is not None and 0.0 < t - previous[0] < SPAN:
            return                                  # within the span: the next residual starts from its start
        self._previous = (t, x.copy())
        if previous is None or t - previous[0] > MAX_HORIZON:
            return
        t0, x0 = previous
        span = t - t0
        lagged = self._lagged(t, span)
        wrenches = np.ascontiguousarray(lagged @ self.matrix.T)
        kernel.predict(self.model, x0, kernel.attitude_trig(x0), wrenches, len(wrenches) - 1, self.slot, span,
                       np.zeros(6), self._out, self._ws)
        self.residual = self.mass @ (x[6:] - self._out[6:]) / span
        self._update(self.residual, _mean_over(lagged, span, self.slot), span)
        self._d_history.append((t, self.healthy.d))
        while self._d_history and self._d_history[0][0] < t - 2 * MAX_HORIZON - MEMORY:
            self._d_history.pop(0)

    def _lagged(self, end: float, span: float) -> np.ndarray:
        """The thrusts told over the `span` s before `end`, per slot as `slot_means` gives them, through the
        thrusters' first-order lag (started `settle` s earlier, from the oldest slot's value)."""
        told = self.thrusts.slot_means(end, span + self.settle, self.slot)
        if self.lag >= 1.0:
            return told[-(int(np.ceil(span / self.slot)) + 1):]
        out = np.empty_like(told)
        y = told[0].copy()
        for k in range(told.shape[0]):
            y += (told[k] - y) * self.lag
            out[k] = y
        return out[-(int(np.ceil(span / self.slot)) + 1):]

    def _update(self, r: np.ndarray, told: np.ndarray, span: float) -> None:
        keep = np.exp(-span / MEMORY)
        self.healthy.step(r, None, self.noise, span, keep)
        for h in self.faulty:
            if not self.excluded[h.thruster]:
                h.step(r, self.matrix[:, h.thruster] * told[h.thruster], self.noise, span, keep)
        best = max([self.healthy, *self.faulty], key=lambda h: h.score)
        k = min(span / NOISE_TIME, 1.0)
        squared = np.minimum(best.innovation ** 2, 9.0 * self.noise)   # a fault's transient does not drown the noise
        self.noise = np.maximum(self.noise + k * (squared - self.noise), NOISE_FLOOR)

    def verdicts(self, t: float) -> list[Verdict]:
        """The thruster newly found not to do what it is told, if any (named once; answer with `answered`)."""
        if self._first is None or t - self._first < WARM_UP or t < self._quiet_until:
            return []
        evidence = np.where(self.excluded, -np.inf, self.evidence)
        order = np.argsort(evidence)[::-1]
        i, second = int(order[0]), evidence[order[1]]
        g = float(self.effectiveness[i])
        scale = AGAIN ** np.count_nonzero(self.known != 1.0)
        if not (evidence[i] > EVIDENCE * scale and evidence[i] - second > MARGIN * scale and g < HEALTHY):
            self._since = None
            return []
        if self._since is None or self._since[0] != i:
            self._since = (i, t)
        if t - self._since[1] < (CONFIRM_REVERSED if g < REVERSED else CONFIRM):
            return []
        return [self._verdict(i, g, self._since[1])]

    def _verdict(self, i: int, g: float, since: float) -> Verdict:
        effectiveness = g * self.known[i]
        if effectiveness < REVERSED:
            return Verdict(i + 1, "reversed", effectiveness, since)
        if effectiveness >= DEAD:
            return Verdict(i + 1, "weak", effectiveness, since)
        push = self._push_along(i, since)
        kind = "stuck" if abs(push) > STUCK_PUSH else "dead"
        return Verdict(i + 1, kind, effectiveness, since, push)

    def _push_along(self, i: int, since: float) -> float:
        """The steady thrust along thruster i's column its hypothesis's disturbance took on since just before
        `since` (a stuck thruster's push is constant: the filter puts it in d)."""
        before = [d for t, d in self._d_history if t <= since - CONFIRM]
        if not before:
            return 0.0
        column = self.matrix[:, i]
        return float(column @ (self.faulty[i].d - before[-1]) / (column @ column))

    def estimate_jumped(self, t: float) -> None:
        """The position estimate jumped at vehicle time t (a fix after a dropout, an EKF reset: `estimate_jumps`):
        its velocity steps with it and the law answers with a burst of thrust, motion no thruster's fault explains
        but any hypothesis can partly fit. Every score starts again and no verdict comes for SETTLE s."""
        for h in (self.healthy, *self.faulty):
            h.score = 0.0
        self._since = None
        self._quiet_until = max(self._quiet_until, t + SETTLE)

    def answered(self, verdict: Verdict) -> None:
        """The allocation now uses `verdict.gain` for the thruster: what it is told is scaled by it from now on.
        Every hypothesis starts again (scores, a_i; the disturbance open to learning: a stuck thruster's push is the
        water's now) and no verdict comes for SETTLE s (a dead or stuck one is no longer told anything)."""
        i = verdict.thruster - 1
        self.known[i] = verdict.gain
        self.excluded[i] = verdict.gain == 0.0
        for h in (self.healthy, *self.faulty):
            h.restart()
        self._since = None
        if self._previous is not None:
            self._quiet_until = self._previous[0] + SETTLE


def _mean_over(ring: np.ndarray, span: float, slot: float) -> np.ndarray:
    """The mean over the last `span` s of the per-slot values `CommandHistory.slot_means(end, span, slot)` gave
    (oldest first; the oldest slots reach further back than `span`)."""
    n = ring.shape[0]
    ends = (n - 1 - np.arange(n)) * slot               # s before `end` at each slot's newer edge
    overlap = np.clip(np.minimum(ends + slot, span) - ends, 0.0, slot)
    return overlap @ ring / span
