"""The runner's answer to a thruster that does not do what it is told: name it, allocate around it, say what authority
is left, and go on only while the mission stays flyable.

`ThrusterHealth` (the estimate) finds the thruster; `Actuation.set_gain` re-solves the allocation with its
effectiveness (a dead or stuck one left out: a BlueROV2 Heavy keeps all six degrees of freedom with any seven of its
eight thrusters); `Allocator.authority` measures what each axis can still get. The mission goes on if the largest
wrench the law asked for on every axis before the fault began (its answer to the fault is no measure of the mission)
is within what is left (with FLYABLE_MARGIN), else the run stops.
"""

from __future__ import annotations

import numpy as np

from rov_mav.flight.thrusters.actuation import Actuation
from rov_mav.flight.run.run_options import Abort
from rov_mav.flight.thrusters.thruster_health import ThrusterHealth, Verdict

AXES = ("surge", "sway", "heave", "roll", "pitch", "yaw")
FLYABLE_MARGIN = 0.8      # the share of an axis's remaining authority the mission may need
EXIT_THRUSTER = 6         # exit status of a run stopped because a thruster failed
LEAD = 3.0                # vehicle s a fault may run before its estimate leaves the healthy range: the mission's need
                          # is what the law asked for before then


class ThrusterWatch:
    """`observe(t, x)` each new measured state, `told(t_act, thrusts, tau)` each command; returns and says what it
    found; raises Abort when the mission cannot be flown with what is left."""

    def __init__(self, model_packed: np.ndarray, actuation: Actuation, slot: float, say):
        self.actuation = actuation
        self.say = say
        self.health = ThrusterHealth(model_packed, actuation.allocator.matrix, slot,
                                     actuation.vehicle.thruster_time_constant)
        self.full = actuation.allocator.authority()
        self._asked: list[tuple[float, np.ndarray]] = []   # (vehicle s, the largest |tau| per axis over that second)
        self.found: list[tuple[float, Verdict]] = []     # (vehicle s it was named, verdict)
        self._healthy_until = np.inf            # vehicle s: what the law asked before this measures the mission

    def told(self, t_act: float, thrusts: np.ndarray, tau: np.ndarray) -> None:
        self.health.told(t_act, thrusts)
        second = float(np.floor(t_act))
        if self._asked and self._asked[-1][0] == second:
            np.maximum(self._asked[-1][1], np.abs(tau), out=self._asked[-1][1])
        else:
            self._asked.append((second, np.abs(tau)))

    def needed(self, before: float) -> np.ndarray:
        """(6,) the largest |tau| per axis the law asked for in the whole seconds before `before` (vehicle s)."""
        rows = [asked for second, asked in self._asked if second + 1.0 <= before]
        return np.max(rows, axis=0) if rows else np.zeros(6)

    def observe(self, t: float, x: np.ndarray) -> None:
        self.health.observe(t, x)
        for verdict in self.health.verdicts(t):
            self._answer(t, verdict)

    def _answer(self, t: float, verdict: Verdict) -> None:
        self.found.append((t, verdict))
        self._healthy_until = min(self._healthy_until, verdict.at - LEAD)   # a second fault: still before the first
        try:
            self.actuation.set_gain(verdict.thruster - 1, verdict.gain)
        except ValueError:                     # the allocation's rank: an axis no thruster left can push
            raise Abort(f"{verdict.describe()}: with it, the thrusters left cannot push along all six axes",
                        EXIT_THRUSTER) from None
        self.health.answered(verdict)
        left = self.actuation.allocator.authority()
        share = left / self.full
        reduced = ", ".join(f"{axis} {s:.0%}" for axis, s in zip(AXES, share) if s < 0.995) or "none lost"
        how = ("left out" if verdict.gain == 0.0 else "flown mirrored" if verdict.gain < 0 else
               f"allocated at {verdict.gain:.0%}")
        self.say(f"{verdict.describe()}: seen at vehicle t={t:.1f} s, {t - verdict.at:.1f} s after it began; {how}, "
                 f"the allocation re-solved over the others (authority left: {reduced})", "warning")
        short = [f"{axis} {need:.1f} of {have:.1f}" for axis, need, have in zip(AXES, self.needed(self._healthy_until), left)
                 if need > FLYABLE_MARGIN * have]
        if short:
            raise Abort(f"{verdict.describe()}: before it, the mission needed more than what is left on "
                        f"{', '.join(short)} (N or N m; at most {FLYABLE_MARGIN:.0%} of it is used)", EXIT_THRUSTER)
