"""The run's own navigation (`run --estimator model`): a model-aided Kalman filter over what passes the vehicle's
router anyway, for when the vehicle's estimate is what limits the error against the truth.

ArduSub's EKF3 predicts with the IMU alone and knows nothing of the vehicle; between two acoustic fixes its position
is the integral of a noisy acceleration, and every fix corrects it with a step. This filter predicts with the
vehicle's dynamics instead (Eq. 2.7 through the compiled model, `kernel.state_derivative`: the controller's own
model, so `identify`'s makes it better) under the wrench the run itself commands, each from the instant it acts, as
AUV navigation does between fixes. Its state is z = [north, east, down, u, v, w, X_d, Y_d, Z_d, current north,
current east]: the position, the body velocity, a slowly varying body force the model does not know (a tether's
pull, buoyancy off by a weight, thrust the thrusters do not give: Eq. 3.2's tau_d, its force part) and the water
current the damping acts through (kernel's relative velocity). The attitude and body rates are the vehicle's
(ATTITUDE); the depth its Bar30 through the EKF (LOCAL_POSITION_NED z, which the EKF takes from the Bar30 with no lag
worth modelling).

Measurements, each fused at its own time of validity (the filter keeps the last HISTORY s of its steps with their
inputs and measurements, goes back to that time, fuses, and steps forward again, fusing again what it had fused
since: what EKF3's delayed horizon does, `NavEKF3_core::UpdateFilter`, without a horizon fixed to the largest
delay):
- an acoustic fix (GPS_INPUT with a fix: north/east from the EKF origin, its horiz_accuracy as the standard
  deviation), valid UGPS_LATENCY before it arrives;
- a DVL report (VISION_POSITION_DELTA: the body velocity over the report's interval), valid DVL_LATENCY before it
  arrives;
- until a source has given a measurement (the run may start in a dropout: the vehicle's estimate is then the best
  there is, the unknown force not yet learnt) and where no source has spoken for SOURCE_SILENCE s (an ideal or a
  GPS-aided vehicle, a driver that died), the vehicle's own horizontal position, so the filter never runs open-loop
  for long; a source in a dropout still speaks (the UGPS driver sends GPS_INPUT without a fix), and the model
  carries the position through it.
Each innovation is gated at GATE standard deviations; after RESET_AFTER s of fixes refused in a row the filter is
reset to the next one, as EKF3 resets its position and velocity to its GPS (`NavEKF3_core::ResetPosition`,
`ResetVelocity`): the filter had gone wrong, not the fixes; the position is the fix's, the velocity the vehicle's own,
the unknown force learnt afresh. The first fix resets the position alone (the position before it was the vehicle's;
the force learnt meanwhile is kept).
What the law flies on is the filter's output, as EKF3's output predictor gives it (`NavEKF3_core::calcOutputStates`,
EK3_TAU_OUTPUT): carried forward by the same model, and its position and velocity moved towards the filter's over
OUTPUT_TIME, so a fix's correction (a few cm, 3.8 times a second) is not a step the law turns into thruster activity;
a jump of the filter beyond JUMP_MIN (a fix after a dropout, a reset) is held out of what the output moves to and
given up at CATCH_UP m/s, as `estimate_jumps` takes in the vehicle's. (Clamping the output's whole correction at
CATCH_UP instead let it drift from the filter for good wherever the velocity's error outran CATCH_UP: seen as 3.8 m
at the start of a square on acoustic fixes.)
Pure: no I/O, no clock.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from rov_mav.flight.state.estimate_jumps import CATCH_UP, JUMP_MIN
from rov_mav.flight.state.prediction import CommandHistory
from rov_mav.model import kernel
from rov_mav.model.navigation import Dvl, Ugps

STILL_WATER = np.zeros(3)
N = 11                    # north, east, down, u, v, w, X_d, Y_d, Z_d, current north, current east
STEP = 0.02               # s: the longest prediction step
DIFFERENCE = 1e-4         # m/s: the step of the Jacobian's differences
HISTORY = 1.5             # s of steps kept to fuse a late measurement at its own time
UGPS_LATENCY = Ugps().latency     # s from a fix to its arrival (the figures of `rov_mav.model.navigation`)
DVL_LATENCY = Dvl().latency
SOURCE_SILENCE = 30.0     # s without a navigation source's message before the vehicle's position is fused
GATE = 5.0                # standard deviations: a larger innovation is refused (EKF3's default position gate)
RESET_AFTER = 5.0         # s of refused fixes in a row before they are taken after all
POSITION, FILTER = "position", "filter"   # what a reset sets (`ModelEstimator._reset`)
PENDING = 64              # measurements at most held for a time the filter has not reached yet
ACCEL_NOISE = 0.05        # m/s^2 per axis: what the model misses of the acceleration (process noise)
POSITION_NOISE = 0.002    # m/sqrt(s): the position's own process noise (rounding of the steps)
FORCE_WALK = 0.05         # N per sqrt(s): how fast the unknown force may change
CURRENT_WALK = 0.001      # m/s per sqrt(s): how fast the water current may change
FIX_FLOOR = 0.05          # m: the least standard deviation given to a fix
DVL_NOISE = 0.02          # m/s per axis: a DVL report's standard deviation (noise and scale error)
DEPTH_NOISE = 0.01        # m: the vehicle's depth
VEHICLE_NOISE = 0.2       # m: the vehicle's horizontal position, when it is what is fused (as good as a fix)
OUTPUT_TIME = 1.0         # s: the time constant the output takes the filter's corrections in over
START_POSITION, START_VELOCITY, START_FORCE, START_CURRENT = 1.0, 0.05, 5.0, 0.03  # at the start (m, m/s, N, m/s)


def _update(z: np.ndarray, P: np.ndarray, H: np.ndarray, y: np.ndarray, R: np.ndarray,
            gate: bool) -> tuple[np.ndarray, np.ndarray] | None:
    """The Kalman update with y = H z + noise(R) (Joseph form: P stays symmetric and positive); None if gated out."""
    innovation = y - H @ z
    S = H @ P @ H.T + R
    S_inv = np.linalg.inv(S)
    if gate and float(innovation @ S_inv @ innovation) > GATE ** 2 * len(y):
        return None
    K = P @ H.T @ S_inv
    IKH = np.eye(len(z)) - K @ H
    return z + K @ innovation, IKH @ P @ IKH.T + K @ R @ K.T


@dataclass
class _Step:
    t: float              # s: the time this step ends at
    h: float              # s: its length
    attitude: np.ndarray  # (6,) roll, pitch, yaw, p, q, r over it
    tau: np.ndarray       # (6,) the commanded wrench over it
    z: np.ndarray         # (N,) the state at t, the measurements of its time fused
    P: np.ndarray         # (N, N)
    F: np.ndarray         # (N, N) the step's transition (kept: stepping forward again after a late fusion reuses it)
    measurements: list = field(default_factory=list)   # (H, y, R) fused at t: fused again when an earlier one is


class ModelEstimator:
    """`commanded(t_act, wrench)` for every command; `advance(t, attitude)` with each state sample; `fix`, `dvl`,
    `depth`, `vehicle` as they arrive; `position`, `velocity` the estimate at the last `advance`."""

    def __init__(self, model_packed: np.ndarray):
        self.model = np.ascontiguousarray(model_packed, dtype=float)
        self.wrenches = CommandHistory(6)
        self.steps: deque[_Step] = deque()
        self.z = np.zeros(N)
        self.out = np.zeros(6)               # what the law sees: the filter's position and velocity, smoothed
        self.held = np.zeros(3)              # m: the filter's jumps the output has still to take in (`_output_step`)
        self.P = np.zeros((N, N))
        self.t: float | None = None
        self.last_source = -math.inf       # s: the last fix or DVL report fused or refused
        self.refused_since: float | None = None   # s: the first of the fixes refused in a row
        self.fused = {"fix": 0, "dvl": 0, "depth": 0, "vehicle": 0}
        self.refused = {"fix": 0, "dvl": 0, "depth": 0, "vehicle": 0}     # gated out
        self.too_old = {"fix": 0, "dvl": 0, "depth": 0, "vehicle": 0}     # valid before the steps kept
        self.ahead = {"fix": 0, "dvl": 0, "depth": 0, "vehicle": 0}       # valid after the filter's time
        self.resets = 0
        self._pending: deque = deque(maxlen=PENDING)   # (t, measurement's method, its arguments): ahead of self.t
        self._vehicle_velocity: np.ndarray | None = None   # the vehicle's own body velocity, the latest given
        self._x = np.zeros(12)
        self._dx = np.zeros(12)
        self._tau = np.zeros(6)
        self._force_to_acceleration = self.model[kernel.P_MINV:kernel.P_MINV + 36].reshape(6, 6)[:3, :3].copy()
        self._Q = np.diag([POSITION_NOISE ** 2] * 3 + [ACCEL_NOISE ** 2] * 3 + [FORCE_WALK ** 2] * 3
                          + [CURRENT_WALK ** 2] * 2)
        self._current = np.zeros(3)

    @property
    def started(self) -> bool:
        return self.t is not None

    def start(self, t: float, eta: np.ndarray, nu: np.ndarray) -> None:
        """Begin at vehicle time t from a known state (the vehicle's estimate when the run takes over)."""
        self.t = t
        self.z = np.concatenate([eta[:3], nu[:3], np.zeros(5)]).astype(float)
        self.P = np.diag([START_POSITION ** 2] * 3 + [START_VELOCITY ** 2] * 3 + [START_FORCE ** 2] * 3
                         + [START_CURRENT ** 2] * 2)
        self.out = self.z[:6].copy()
        self.held = np.zeros(3)
        self.steps.clear()
        self.steps.append(_Step(t, 0.0, np.concatenate([eta[3:6], nu[3:6]]).astype(float), np.zeros(6),
                                self.z.copy(), self.P.copy(), np.eye(N)))

    def commanded(self, t_act: float, wrench: np.ndarray) -> None:
        """A wrench that acts from vehicle time t_act (until the next one)."""
        self.wrenches.add(t_act, np.asarray(wrench, dtype=float))

    def advance(self, t: float, attitude: np.ndarray) -> None:
        """Step to vehicle time t; attitude (6,) = roll, pitch, yaw, p, q, r as the vehicle reports them at t."""
        attitude = np.asarray(attitude, dtype=float)
        while self.t is not None and t - self.t > 1e-9:
            h = min(STEP, t - self.t)
            tau = self.wrenches.slot_means(self.t + h, h, h)[-1]
            F = self._transition(self.z, attitude, tau, h)
            self.z, self.P = self._predict(self.z, self.P, attitude, tau, h, F)
            self._output_step(attitude, tau, h)
            self.t += h
            self.steps.append(_Step(self.t, h, attitude, tau, self.z.copy(), self.P.copy(), F))
        while len(self.steps) > 1 and self.steps[1].t < (self.t or 0.0) - HISTORY:
            self.steps.popleft()
        while self._pending and self.t is not None and self._pending[0][0] <= self.t + STEP:
            _, method, args = self._pending.popleft()
            method(*args)

    def _output_step(self, attitude: np.ndarray, tau: np.ndarray, h: float) -> None:
        """The output carried by the model like the filter and moved towards the filter's estimate by h /
        OUTPUT_TIME of the difference (EKF3's output predictor: position and velocity both, so it cannot drift from
        the filter whatever the velocity's error); the filter's jumps (`held`: a fix after a dropout, a reset) are
        left out of what it moves to, and given up at CATCH_UP m/s: the vehicle is not sent lunging at them."""
        self.out = self.out + h * self._derivative(np.concatenate([self.out, self.z[6:]]), attitude, tau)[:6]
        size = float(np.linalg.norm(self.held))
        self.held *= max(size - CATCH_UP * h, 0.0) / size if size > 0.0 else 0.0
        target = self.z[:6].copy()
        target[:3] -= self.held
        self.out += min(h / OUTPUT_TIME, 1.0) * (target - self.out)

    @property
    def position(self) -> np.ndarray:
        """The output's position (the filter's, its corrections taken in over OUTPUT_TIME)."""
        return self.out[:3].copy()

    @property
    def velocity(self) -> np.ndarray:
        """The output's body velocity u, v, w."""
        return self.out[3:6].copy()

    @property
    def sourced(self) -> bool:
        """A navigation source has given a measurement (a fix or a DVL report fused)."""
        return self.fused["fix"] + self.fused["dvl"] > 0

    def heard(self, t: float) -> None:
        """A navigation source spoke at vehicle time t (with a fix or without: a dropout is not a silence, and the
        vehicle's own position, dead-reckoned through it, is no better than the model's)."""
        self.last_source = max(self.last_source, t)

    def fix(self, arrival: float, north: float, east: float, std: float) -> bool:
        """An acoustic fix that arrived at vehicle time `arrival`; True if fused."""
        self.heard(arrival)
        t = arrival - UGPS_LATENCY
        H = np.zeros((2, N))
        H[0, 0] = H[1, 1] = 1.0
        R = np.eye(2) * max(std, FIX_FLOOR) ** 2
        if self._ahead(t, self.fix, (arrival, north, east, std)):
            return False
        fused = self._fuse(t, H, np.array([north, east]), R, "fix", reset=self._reset_due(arrival))
        if fused:
            self.refused_since = None
        elif self.refused_since is None:
            self.refused_since = arrival
        return fused

    def dvl(self, arrival: float, velocity: np.ndarray) -> bool:
        """A DVL report's body velocity that arrived at vehicle time `arrival`; True if fused."""
        self.heard(arrival)
        if self._ahead(arrival - DVL_LATENCY, self.dvl, (arrival, velocity)):
            return False
        H = np.zeros((3, N))
        H[:, 3:6] = np.eye(3)
        return self._fuse(arrival - DVL_LATENCY, H, np.asarray(velocity, dtype=float), np.eye(3) * DVL_NOISE ** 2,
                          "dvl")

    def depth(self, t: float, down: float) -> bool:
        H = np.zeros((1, N))
        H[0, 2] = 1.0
        return self._fuse(t, H, np.array([down]), np.eye(1) * DEPTH_NOISE ** 2, "depth")

    def vehicle(self, t: float, north: float, east: float, velocity: np.ndarray) -> bool:
        """The vehicle's own estimate at t: its body velocity u, v, w (what a reset starts the velocity from) and its
        horizontal position, fused until a navigation source has given a measurement, and again once none has spoken
        for SOURCE_SILENCE s."""
        self._vehicle_velocity = np.asarray(velocity, dtype=float).copy()
        if self.sourced and t - self.last_source < SOURCE_SILENCE:
            return False
        H = np.zeros((2, N))
        H[0, 0] = H[1, 1] = 1.0
        return self._fuse(t, H, np.array([north, east]), np.eye(2) * VEHICLE_NOISE ** 2, "vehicle")

    def _reset_due(self, arrival: float) -> str | None:
        """POSITION for the first fix (what came before was the vehicle's estimate), FILTER for one after
        RESET_AFTER s of fixes refused in a row (the filter has gone wrong, not the fixes): `_reset`."""
        if not self.sourced:
            return POSITION
        if self.refused_since is not None and arrival - self.refused_since >= RESET_AFTER:
            return FILTER
        return None

    def _ahead(self, t: float, method, args: tuple) -> bool:
        """A measurement valid after the filter's time (stamped with the vehicle clock's now, which runs on between
        the state samples the filter steps to, and before the first of them) is held, and given again by `advance`
        once the filter gets there."""
        if self.t is None or t <= self.t + STEP:
            return False
        if len(self._pending) == PENDING:
            self.too_old[method.__name__] += 1      # the oldest held, never reached: dropped
        self.ahead[method.__name__] += 1
        self._pending.append((t, method, args))
        return True

    def _reset(self, z: np.ndarray, P: np.ndarray, position: np.ndarray, R: np.ndarray,
               what: str) -> tuple[np.ndarray, np.ndarray]:
        """The position set to the fix's (EKF3's `NavEKF3_core::ResetPosition`); for FILTER also the velocity to the
        vehicle's own, when it has given one (`ResetVelocity`), the unknown force learnt afresh (a filter that refused
        its fixes may have put its own error there, cancelling thrust) and the current's uncertainty widened. What is
        reset is unlinked from the rest."""
        z, P = z.copy(), P.copy()
        z[:2] = position
        reset = [0, 1]
        if what == FILTER:
            reset += [6, 7, 8, 9, 10]
            z[6:9] = 0.0
            if self._vehicle_velocity is not None:
                z[3:6] = self._vehicle_velocity
                reset += [3, 4, 5]
        P[reset, :], P[:, reset] = 0.0, 0.0
        P[:2, :2] = R
        if what == FILTER:
            if self._vehicle_velocity is not None:
                P[3:6, 3:6] = np.eye(3) * START_VELOCITY ** 2
            P[6:9, 6:9] = np.eye(3) * START_FORCE ** 2
            P[9:11, 9:11] = np.eye(2) * START_CURRENT ** 2
        return z, P

    def _fuse(self, t: float, H: np.ndarray, y: np.ndarray, R: np.ndarray, kind: str,
              reset: str | None = None) -> bool:
        """Fuse y = H z + noise(R) at vehicle time t (a step's end at or before it), then step forward again."""
        if self.t is None or not self.steps:
            return False
        if t < self.steps[0].t:
            self.too_old[kind] += 1
            return False
        k = len(self.steps) - 1
        while k > 0 and self.steps[k].t > t:
            k -= 1
        step = self.steps[k]
        z, P = step.z, step.P
        if reset:
            self.resets += 1
        updated = self._reset(z, P, y, R, reset) if reset else _update(z, P, H, y, R, gate=True)
        if updated is None:
            self.refused[kind] += 1
            return False
        step.z, step.P = updated
        step.measurements.append((H, y, R))
        z, P = updated
        for later in list(self.steps)[k + 1:]:
            z, P = self._predict(z, P, later.attitude, later.tau, later.h, later.F)
            for measurement in later.measurements:
                z, P = _update(z, P, *measurement, gate=False)
            later.z, later.P = z, P
        jump = z[:3] - self.z[:3]
        if float(np.linalg.norm(jump)) > JUMP_MIN:
            self.held += jump
        self.z, self.P = z.copy(), P.copy()
        self.fused[kind] += 1
        return True

    def _derivative(self, z: np.ndarray, attitude: np.ndarray, tau: np.ndarray) -> np.ndarray:
        x = self._x
        x[0:3], x[3:6], x[6:9], x[9:12] = z[0:3], attitude[0:3], z[3:6], attitude[3:6]
        self._tau[:] = tau
        self._tau[:3] += z[6:9]
        self._current[:2] = z[9:11]
        kernel.state_derivative(self.model, x, self._tau, self._current, self._dx)
        return np.concatenate([self._dx[0:3], self._dx[6:9], np.zeros(5)])

    def _transition(self, z: np.ndarray, attitude: np.ndarray, tau: np.ndarray, h: float) -> np.ndarray:
        """F = I + h df/dz at z: the position enters no derivative, the force enters the acceleration through
        M^-1's translational block; the velocity's and the current's columns by forward differences."""
        J = np.zeros((N, N))
        J[3:6, 6:9] = self._force_to_acceleration
        f = self._derivative(z, attitude, tau)
        for i in (3, 4, 5, 9, 10):
            d = z.copy()
            d[i] += DIFFERENCE
            J[:, i] = (self._derivative(d, attitude, tau) - f) / DIFFERENCE
        return np.eye(N) + h * J

    def _predict(self, z: np.ndarray, P: np.ndarray, attitude: np.ndarray, tau: np.ndarray, h: float,
                 F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """One Euler step of the model, and of the covariance through F."""
        return z + h * self._derivative(z, attitude, tau), F @ P @ F.T + self._Q * h
