"""The runner's answer to a thruster that does not do what it is told: name it, allocate around it, say what authority
is left, and go on only while the mission stays flyable.

`ThrusterHealth` (the estimate) finds the thruster; `Actuation.set_gain` re-solves the allocation with its
effectiveness (a dead or stuck one left out: a BlueROV2 Heavy keeps all six degrees of freedom with any seven of its
eight thrusters); `Allocator.authority` measures what each axis can still get. The mission goes on if the largest
wrench the law has asked for so far on every axis is within what is left (with FLYABLE_MARGIN), else the run stops.
"""

from __future__ import annotations

import numpy as np

from rov_mav.flight.actuation import Actuation
from rov_mav.flight.run_options import Abort
from rov_mav.flight.thruster_health import ThrusterHealth, Verdict

AXES = ("surge", "sway", "heave", "roll", "pitch", "yaw")
FLYABLE_MARGIN = 0.8      # the share of an axis's remaining authority the mission may need
EXIT_THRUSTER = 6         # exit status of a run stopped because a thruster failed


class ThrusterWatch:
    """`observe(t, x)` each new measured state, `told(t_act, thrusts, tau)` each command; returns and says what it
    found; raises Abort when the mission cannot be flown with what is left."""

    def __init__(self, model_packed: np.ndarray, actuation: Actuation, slot: float, say):
        self.actuation = actuation
        self.say = say
        self.health = ThrusterHealth(model_packed, actuation.allocator.matrix, slot,
                                     actuation.vehicle.thruster_time_constant)
        self.full = actuation.allocator.authority()
        self.needed = np.zeros(6)              # the largest |tau| per axis the law has asked for
        self.found: list[tuple[float, Verdict]] = []     # (vehicle s it was named, verdict)

    def told(self, t_act: float, thrusts: np.ndarray, tau: np.ndarray) -> None:
        self.health.told(t_act, thrusts)
        np.maximum(self.needed, np.abs(tau), out=self.needed)

    def observe(self, t: float, x: np.ndarray) -> None:
        self.health.observe(t, x)
        for verdict in self.health.verdicts(t):
            self._answer(t, verdict)

    def _answer(self, t: float, verdict: Verdict) -> None:
        self.found.append((t, verdict))
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
        self.say(f"{verdict.describe()}: seen {t - verdict.at:.1f} s after it began; {how}, the allocation re-solved "
                 f"over the others (authority left: {reduced})", "warning")
        short = [f"{axis} {need:.1f} of {have:.1f}" for axis, need, have in zip(AXES, self.needed, left)
                 if need > FLYABLE_MARGIN * have]
        if short:
            raise Abort(f"{verdict.describe()}: the mission has needed more than what is left on "
                        f"{', '.join(short)} (N or N m; at most {FLYABLE_MARGIN:.0%} of it is used)", EXIT_THRUSTER)
