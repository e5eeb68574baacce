"""A position estimate that jumps (an acoustic fix after a dropout, a DVL or EKF reset), taken in at a pace the
vehicle can fly instead of all at once.

An EKF's LOCAL_POSITION_NED carries no reset counter (`GCS_MAVLINK::send_local_position`): a reset shows only as a
jump. Each new position is set against where the previous one, carried forward by the reported NED velocity, says
the vehicle is; what it moved beyond that is the estimator's correction. A reset moves it at once; a fix after a
dropout reaches the report spread over about EK3_TAU_OUTPUT (0.25 s: EKF3's output predictor,
`NavEKF3_core::calcOutputStates`). So a correction faster than ONSET_RATE (no motion: the vehicle cannot fly that
fast) and beyond what the estimate's own scatter allows (JUMP_SIGMAS times its learnt standard deviation) starts a
hold: it and every correction for FOLLOW s after it are held as an offset, the law sees the position without them,
and the offset is brought back to zero as along a slow path: at CATCH_UP m/s, speeding up and slowing down at
CATCH_ACCEL m/s^2 (a step in the pace is a step in the velocity the law sees, and a kick of thrust), so the vehicle
moves to where the estimate now puts it without the thrust a metre of sudden error asks for. A hold that came to
JUMP_MIN or more is a jump, listed when its FOLLOW s are over. Pure: no I/O, no clock.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

JUMP_MIN = 0.25           # m: a smaller hold is not listed as a jump
JUMP_SIGMAS = 8.0         # a correction within this many standard deviations of the estimate's own scatter is not held
ONSET_RATE = 1.0          # m/s: ... nor one slower than this (a BlueROV2's top speed: it could be motion)
FOLLOW = 1.0              # s: the corrections after a hold's start that belong to it (4 x EK3_TAU_OUTPUT)
CATCH_UP = 0.1            # m/s: the pace a jump is taken in at (half the default lead-in's speed)
CATCH_ACCEL = 0.05        # m/s^2: how fast that pace is reached and left
SCATTER_TIME = 5.0        # s: time constant of the learnt scatter
SCATTER_START = 0.02      # m: the scatter assumed before any is learnt
MAX_GAP = 2.0             # s: after a longer silence the position is taken as it is (nothing to carry forward)


@dataclass(frozen=True)
class Jump:
    t: float              # vehicle s of the position that jumped
    step: np.ndarray      # (3,) m, NED: how far the estimate jumped beyond where its motion put it
    seen: float           # vehicle s it was listed (FOLLOW s after t)

    def describe(self) -> str:
        n, e, d = self.step
        size = float(np.linalg.norm(self.step))
        return (f"the position estimate jumped {size:.2f} m (north {n:+.2f}, east {e:+.2f}, down {d:+.2f}) beyond "
                f"its own motion: a fix after a dropout or a reset; taken in at {CATCH_UP:g} m/s over "
                f"{catch_up_time(size):.0f} s")


def catch_up_time(distance: float) -> float:
    """s to take in `distance` m: CATCH_UP m/s, reached and left at CATCH_ACCEL (a triangle when too short)."""
    ramp = CATCH_UP / CATCH_ACCEL
    if distance >= CATCH_UP * ramp:
        return distance / CATCH_UP + ramp
    return 2.0 * np.sqrt(distance / CATCH_ACCEL)


class EstimateJumps:
    """`steady(t, position, v_ned)` -> the position the law sees (the reported one less the jumps still being taken
    in); `jumps` lists every jump seen, `offset` is what is still held, `catch_up` (3,) m/s the rate at which it is
    being given up (what the seen position moves by beyond the reported velocity)."""

    def __init__(self):
        self.offset = np.zeros(3)
        self.jumps: list[Jump] = []
        self._scatter = SCATTER_START ** 2
        self._pace = 0.0                      # m/s the offset is being taken in at
        self._last: tuple[float, np.ndarray, np.ndarray] | None = None   # (t, position seen, NED velocity)
        self._hold: tuple[float, np.ndarray] | None = None     # (vehicle s it started, what it has held)
        self.catch_up = np.zeros(3)

    def steady(self, t: float, position: np.ndarray, v_ned: np.ndarray) -> np.ndarray:
        position = np.asarray(position, dtype=float)
        last, self._last = self._last, None
        self.catch_up = np.zeros(3)
        if last is not None and 0.0 < t - last[0] <= MAX_GAP:
            dt = t - last[0]
            correction = position - self.offset - (last[1] + last[2] * dt)
            size = float(np.linalg.norm(correction))
            if self._hold is not None:
                self._hold = (self._hold[0], self._hold[1] + correction)
                self.offset = self.offset + correction
            elif size > max(ONSET_RATE * dt, JUMP_SIGMAS * np.sqrt(self._scatter)):
                self._hold = (t, correction)
                self.offset = self.offset + correction
            else:
                self._scatter += min(dt / SCATTER_TIME, 1.0) * (size ** 2 / 3.0 - self._scatter)
            if self._hold is not None and t - self._hold[0] >= FOLLOW:
                if np.linalg.norm(self._hold[1]) >= JUMP_MIN:
                    self.jumps.append(Jump(self._hold[0], self._hold[1], t))
                self._hold = None
            held = float(np.linalg.norm(self.offset))
            if held > 0.0:     # speed up, cruise, or brake so as to stop where the offset ends
                self._pace = min(self._pace + CATCH_ACCEL * dt, CATCH_UP, np.sqrt(2.0 * CATCH_ACCEL * held))
                given_up = self.offset * (1.0 - max(held - self._pace * dt, 0.0) / held)
                self.offset = self.offset - given_up
                self.catch_up = given_up / dt
            else:
                self._pace = 0.0
        seen = position - self.offset
        self._last = (t, seen, np.asarray(v_ned, dtype=float))
        return seen
