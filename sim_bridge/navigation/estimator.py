"""The autopilot's estimator in the built-in vehicle, standing in for ArduPilot's EKF3 (`libraries/AP_NavEKF3`).

Two Kalman filters, run at the sensors' rates (the IMU's, 50 Hz by default, not the 400 Hz main loop):
- heading: [yaw, gyro bias about the vertical], predicted with the gyro (the Euler yaw rate from the body rates and
  the AHRS's roll and pitch), corrected by the compass (its bias is not observable: the heading stays off by it);
- translation: [north, east, down, v_north, v_east, v_down], predicted with the IMU's delta velocities rotated to
  NED by the estimated attitude, corrected by the Bar30 (down), the DVL (body velocity rotated by the attitude of its
  time: `NavEKF3_core::FuseBodyVel`) and the acoustic fix (north, east: `FuseVelPosNED`).
Delayed fusion as EKF3's (`NavEKF3_core::UpdateFilter`, `storedIMU`): the filter runs on a delayed time horizon,
`horizon` behind now (the largest delay the EKF assumes for a source); each measurement is stamped with its arrival
less the delay the EKF assumes for it and fused when the horizon reaches that stamp, in time order. A source whose
real latency exceeds the assumed delay is fused at the wrong time, and the estimate lags by the difference.
The output, what the vehicle reports, is EKF3's output predictor (`NavEKF3_core::calcOutputStates`): a state of its
own propagated to now with every IMU sample and kept for each sample since the horizon; each time the filter steps,
the difference e between the filter's state and the output kept for the horizon's time is fed back to all the kept
outputs and to now's as a PI correction, K e + 0.1 K^2 sum(e) with K = dt / TAU_OUTPUT (EK3_TAU_OUTPUT, 25 cs): a
fix's correction reaches the report spread over about TAU_OUTPUT, not as a step. A reset moves the outputs at once.
Each innovation is gated as EKF3 does (5 standard deviations for position, velocity and height, 3 for the compass:
EK3_POS_I_GATE, EK3_VEL_I_GATE, EK3_HGT_I_GATE, EK3_MAG_I_GATE defaults); the test ratios, innovation^2 /
(gate^2 x innovation variance), are what EKF_STATUS_REPORT reports (as their square roots, `getVariances`). A position
fix rejected when no fix has passed for the retry time (7 s, 10 s with the DVL's velocity aiding: `posTimeout`,
`posRetryTimeNoVel_ms` / `posRetryTimeUseVel_ms`, `NavEKF3_core::setAidingMode`) resets the position, the filter's and
every output's, to the fix (`FuseVelPosNED`, `ResetPosition`): a jump. `nis` keeps each fused measurement's
normalised innovation squared and its dimension.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from rov_mav.model.dynamics import attitude_rotation
from rov_mav.model.navigation import Navigation
from sim_bridge.navigation.sensors import Bar30Sample, CompassSample, DvlReport, ImuSample, UgpsFix

POS_GATE, VEL_GATE, HGT_GATE, MAG_GATE = 5.0, 5.0, 5.0, 3.0
RETRY_NO_VEL, RETRY_WITH_VEL = 7.0, 10.0        # s without a fix passing before a rejected one resets the position
TAU_OUTPUT = 0.25             # s, EK3_TAU_OUTPUT's default (25 cs)
INITIAL_POS_STD, INITIAL_VEL_STD = 0.1, 0.05      # m, m/s at initialisation (the start is known: chosen)
HEADING_STD, BIAS_STD, BIAS_WALK = 0.05, 0.005, 1e-5   # rad, rad/s, rad/s per sqrt(s) (chosen)
NIS_MEMORY = 4000


def _wrap(a: float) -> float:
    return (a + math.pi) % (2 * math.pi) - math.pi


class Estimator:
    """One boot's estimator, started at vehicle time t0 from the state (eta, nu) it is initialised with."""

    def __init__(self, nav: Navigation, t0: float, eta: np.ndarray, nu: np.ndarray):
        self.nav = nav
        delays = [s.ekf_delay for s in (nav.dvl, nav.ugps) if s is not None]
        self.horizon = max(delays, default=0.0)
        r = attitude_rotation(*eta[3:6])
        self.x = np.concatenate((np.asarray(eta[:3], float), r @ np.asarray(nu[:3], float)))
        self.P = np.diag([INITIAL_POS_STD ** 2] * 3 + [INITIAL_VEL_STD ** 2] * 3)
        self.t_h = t0                                   # the horizon's time
        self.psi, self.bias = float(eta[5]), 0.0
        self.Ph = np.diag([HEADING_STD ** 2, BIAS_STD ** 2])
        self.roll, self.pitch = float(eta[3]), float(eta[4])
        self.rates = np.asarray(nu[3:6], float).copy()
        self._buffer: deque = deque()                   # (t, dt, dv_ned, roll, pitch, psi) past the horizon
        self._queue: list = []                          # (t_fuse, order, kind, item), in fusion order
        self._order = 0
        self._attitude_h = (self.roll, self.pitch, self.psi)
        self.ratios = {"vel": 0.0, "pos": 0.0, "hgt": 0.0, "mag": 0.0}
        self.nis: deque = deque(maxlen=NIS_MEMORY)      # (kind, nis, dim)
        self.aided_at = t0 if nav.has_position_source else -math.inf
        self.glitching = False                          # the last position fix was rejected
        self._passed_at = t0                            # horizon time of the last position fix that passed
        self.retry = RETRY_WITH_VEL if nav.dvl is not None else RETRY_NO_VEL
        self.resets = 0
        self._now = (self.x[:3].copy(), self.x[3:].copy())     # the output predictor's state at now
        self._kept: deque = deque()                     # its state at each IMU sample still past the horizon
        self._sum_error = np.zeros(6)                   # the PI correction's integral
        self.output = (np.concatenate((self.x[:3], np.asarray(eta[3:6], float))), np.asarray(nu, float).copy())
        self._fq: dict[float, tuple[np.ndarray, np.ndarray]] = {}

    # -- inputs ------------------------------------------------------------------------------------------------

    def feed(self, item) -> None:
        if isinstance(item, ImuSample):
            self._imu(item)
        elif isinstance(item, CompassSample):
            self._compass(item)
        elif isinstance(item, Bar30Sample):
            self._enqueue(item.t, "hgt", item)
        elif isinstance(item, DvlReport):
            self._enqueue(item.arrival - self.nav.dvl.ekf_delay, "vel", item)
        elif isinstance(item, UgpsFix) and item.valid:
            self._enqueue(item.arrival - self.nav.ugps.ekf_delay, "pos", item)

    def _enqueue(self, t_fuse: float, kind: str, item) -> None:
        self._order += 1
        self._queue.append((max(t_fuse, self.t_h), self._order, kind, item))
        self._queue.sort(key=lambda q: (q[0], q[1]))

    def _imu(self, s: ImuSample) -> None:
        self.roll, self.pitch = s.roll, s.pitch
        self._heading_predict(s)
        r = attitude_rotation(self.roll, self.pitch, self.psi)
        dv = r @ s.dv_body
        self._buffer.append((s.t, s.dt, dv, self.roll, self.pitch, self.psi))
        p, v = self._now
        v_next = v + dv
        self._now = (p + 0.5 * (v + v_next) * s.dt, v_next)
        self._kept.append(self._now)
        self.rates = s.gyro - np.array([0.0, 0.0, self.bias])
        while self._buffer and self._buffer[0][0] <= s.t - self.horizon + 1e-9:
            t, dt, dv_h, *attitude = self._buffer.popleft()
            self._fuse_due(self.t_h)
            self._predict(dt, dv_h)
            self.t_h, self._attitude_h = t, tuple(attitude)
            self._fuse_due(self.t_h)
            self._correct_outputs(dt, self._kept.popleft())
        p, v = self._now
        self.output = (np.array([p[0], p[1], p[2], self.roll, self.pitch, self.psi]),
                       np.concatenate((r.T @ v, self.rates)))

    def _correct_outputs(self, dt: float, kept: tuple[np.ndarray, np.ndarray]) -> None:
        """The output predictor's PI feedback (`calcOutputStates`): the filter's state less the output kept for the
        horizon's time, fed back to every kept output and to now's."""
        error = self.x - np.concatenate(kept)
        self._sum_error += error
        k = dt / max(TAU_OUTPUT, dt)
        shift = k * error + 0.1 * k * k * self._sum_error
        self._kept = deque((p + shift[:3], v + shift[3:]) for p, v in self._kept)
        self._now = (self._now[0] + shift[:3], self._now[1] + shift[3:])

    # -- heading -----------------------------------------------------------------------------------------------

    def _heading_predict(self, s: ImuSample) -> None:
        _, q, r = s.gyro
        yaw_rate = (q * math.sin(self.roll) + (r - self.bias) * math.cos(self.roll)) / max(math.cos(self.pitch), 0.1)
        self.psi = _wrap(self.psi + yaw_rate * s.dt)
        g = self.nav.imu.gyro_noise
        f = np.array([[1.0, -s.dt], [0.0, 1.0]])
        self.Ph = f @ self.Ph @ f.T + np.diag([(g * s.dt) ** 2 + 1e-8 * s.dt, BIAS_WALK ** 2 * s.dt])

    def _compass(self, c: CompassSample) -> None:
        innovation = _wrap(c.heading - self.psi)
        s = self.Ph[0, 0] + self.nav.compass.noise ** 2
        self.ratios["mag"] = innovation ** 2 / (MAG_GATE ** 2 * s)
        if self.ratios["mag"] > 1.0:
            return
        k = self.Ph[:, 0] / s
        self.psi = _wrap(self.psi + k[0] * innovation)
        self.bias += k[1] * innovation
        self.Ph = self.Ph - np.outer(k, self.Ph[0, :])
        self.nis.append(("mag", innovation ** 2 / s, 1))

    # -- translation ---------------------------------------------------------------------------------------------

    def _fq_of(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        key = round(dt, 6)
        if key not in self._fq:
            imu = self.nav.imu
            q = imu.accel_process ** 2 + imu.accel_noise ** 2
            f = np.eye(6)
            f[:3, 3:] = np.eye(3) * dt
            g = np.r_[np.full(3, 0.5 * dt * dt), np.full(3, dt)]
            qm = np.zeros((6, 6))
            for i in range(3):
                block = q * np.array([[g[i] ** 2, g[i] * g[i + 3]], [g[i] * g[i + 3], g[i + 3] ** 2]])
                qm[np.ix_([i, i + 3], [i, i + 3])] = block
            self._fq[key] = (f, qm)
        return self._fq[key]

    def _predict(self, dt: float, dv: np.ndarray) -> None:
        f, q = self._fq_of(dt)
        self.x[:3] += self.x[3:] * dt + 0.5 * dv * dt
        self.x[3:] += dv
        self.P = f @ self.P @ f.T + q

    def _fuse_due(self, t: float) -> None:
        while self._queue and self._queue[0][0] <= t + 1e-9:
            _, _, kind, item = self._queue.pop(0)
            if kind == "hgt":
                self._update(kind, np.array([2]), np.array([item.depth]), self.nav.bar30.noise ** 2, HGT_GATE,
                             item)
            elif kind == "vel":
                v = attitude_rotation(*self._attitude_h) @ item.velocity
                self._update(kind, np.array([3, 4, 5]), v, self.nav.dvl.noise ** 2, VEL_GATE, item)
            else:
                std = max(item.std, self.nav.ugps.noise_floor)
                self._update(kind, np.array([0, 1]), np.array([item.north, item.east]), std ** 2, POS_GATE, item)

    def _update(self, kind: str, idx: np.ndarray, z: np.ndarray, r: float, gate: float, item) -> None:
        y = z - self.x[idx]
        s = self.P[np.ix_(idx, idx)] + np.eye(len(idx)) * r
        s_inv = np.linalg.inv(s)
        nis = float(y @ s_inv @ y)
        self.ratios[kind] = nis / (gate ** 2 * len(idx))
        accepted = self.ratios[kind] <= 1.0
        if kind == "pos":
            self.glitching = not accepted
            if accepted:
                self._passed_at = self.t_h
            elif self.t_h - self._passed_at > self.retry:      # EKF3 gives up on its own estimate
                self.x[idx] = z
                self.P[idx, :] = 0.0
                self.P[:, idx] = 0.0
                self.P[np.ix_(idx, idx)] = np.eye(len(idx)) * r
                self._kept = deque((np.r_[z, p[2]], v) for p, v in self._kept)
                self._now = (np.r_[z, self._now[0][2]], self._now[1])
                self.resets += 1
                self._passed_at, self.glitching = self.t_h, False
                self.aided_at = item.arrival
                return
        if not accepted:
            return
        k = self.P[:, idx] @ s_inv
        self.x += k @ y
        self.P = self.P - k @ self.P[idx, :]
        self.P = 0.5 * (self.P + self.P.T)
        self.nis.append((kind, nis, len(idx)))
        if kind in ("vel", "pos"):
            self.aided_at = max(self.aided_at, item.arrival)

    # -- reports -----------------------------------------------------------------------------------------------

    def variances(self) -> tuple[float, float, float, float]:
        """(velocity, horizontal position, height, compass) as EKF_STATUS_REPORT carries them: the square roots
        of the last test ratios (`NavEKF3_core::getVariances`)."""
        r = self.ratios
        return math.sqrt(r["vel"]), math.sqrt(r["pos"]), math.sqrt(r["hgt"]), math.sqrt(r["mag"])

    def position_std(self) -> float:
        """m: the horizontal position's standard deviation at the horizon."""
        return math.sqrt(max(self.P[0, 0], self.P[1, 1]))
