"""The autopilot's estimator in the built-in vehicle, standing in for ArduPilot's EKF3 (`libraries/AP_NavEKF3`).

Two Kalman filters, run at the sensors' rates (the IMU's, 50 Hz by default, not the 400 Hz main loop):
- heading: [yaw, gyro bias about the vertical], predicted with the gyro (the Euler yaw rate from the body rates and
  the AHRS's roll and pitch), corrected by the compass (its bias is not observable: the heading stays off by it);
- translation: [north, east, down, v_north, v_east, v_down], predicted with the IMU's delta velocities rotated to
  NED by the estimated attitude, corrected by the Bar30 (down), the DVL (body velocity rotated by the attitude of its
  time: `NavEKF3_core::FuseBodyVel`) and the acoustic fix (north, east: `FuseVelPosNED`).
Delayed fusion as EKF3's (`NavEKF3_core::UpdateFilter`, `storedIMU`, `calcOutputStates`): the filter runs on a
delayed time horizon, `horizon` behind now (the largest delay the EKF assumes for a source); each measurement is
stamped with its arrival less the delay the EKF assumes for it and fused when the horizon reaches that stamp, in time
order; the output is the horizon's state predicted to now through the IMU samples since (EKF3's output predictor,
here without its complementary-filter smoothing: a correction shows at once as a step). Not yet as ArduSub: EKF3
spreads each correction over EK3_TAU_OUTPUT (25 cs; `NavEKF3_core::calcOutputStates`, a PI on the history of outputs;
only a reset, `ResetPositionNE`, moves the output at once). Emulated, it made the run's thruster watch take a 10 cm
fix correction spread over 0.3 s for a reversed thruster (square, ugps, seed 2, vehicle t 202 s), and the run's jump
handling misses spread corrections: both must learn it before the stand-in follows EKF3 here. A source whose real
latency exceeds the assumed delay is fused at the wrong time, and the estimate lags by the difference.
Each innovation is gated as EKF3 does (5 standard deviations for position, velocity and height, 3 for the compass:
EK3_POS_I_GATE, EK3_VEL_I_GATE, EK3_HGT_I_GATE, EK3_MAG_I_GATE defaults); the test ratios, innovation^2 /
(gate^2 x innovation variance), are what EKF_STATUS_REPORT reports (as their square roots, `getVariances`). Position
fixes rejected for RESET_AFTER in a row reset the position to the fix (EKF3 resets to the GPS after its retry time:
`ResetPosition`): a jump. `nis` keeps each fused measurement's normalised innovation squared and its dimension.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from rov_mav.model.navigation import Navigation
from sim_bridge.sensors import Bar30Sample, CompassSample, DvlReport, ImuSample, UgpsFix, rot

POS_GATE, VEL_GATE, HGT_GATE, MAG_GATE = 5.0, 5.0, 5.0, 3.0
RESET_AFTER = 5.0             # s of position fixes rejected in a row before a reset to the fix (chosen)
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
        r = rot(*eta[3:6])
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
        self._rejected_since: float | None = None
        self.resets = 0
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
        r = rot(self.roll, self.pitch, self.psi)
        self._buffer.append((s.t, s.dt, r @ s.dv_body, self.roll, self.pitch, self.psi))
        self.rates = s.gyro - np.array([0.0, 0.0, self.bias])
        while self._buffer and self._buffer[0][0] <= s.t - self.horizon + 1e-9:
            t, dt, dv, *attitude = self._buffer.popleft()
            self._fuse_due(self.t_h)
            self._predict(dt, dv)
            self.t_h, self._attitude_h = t, tuple(attitude)
        self._fuse_due(self.t_h)
        self._output(r)

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
                v = rot(*self._attitude_h) @ item.velocity
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
                self._rejected_since = None
            else:
                self._rejected_since = self._rejected_since if self._rejected_since is not None else self.t_h
                if self.t_h - self._rejected_since >= RESET_AFTER:      # EKF3 gives up on its own estimate
                    self.x[idx] = z
                    self.P[idx, :] = 0.0
                    self.P[:, idx] = 0.0
                    self.P[np.ix_(idx, idx)] = np.eye(len(idx)) * r
                    self.resets += 1
                    self._rejected_since, self.glitching = None, False
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

    def _output(self, r_now: np.ndarray) -> None:
        """The horizon's state predicted to now through the IMU samples since (mean only)."""
        p, v = self.x[:3], self.x[3:]
        if self._buffer:
            dts = np.fromiter((b[1] for b in self._buffer), float, len(self._buffer))
            dvs = np.array([b[2] for b in self._buffer])
            after = np.cumsum(dts[::-1])[::-1] - dts          # time from the end of each sample to now
            p = p + v * dts.sum() + ((0.5 * dts + after)[:, None] * dvs).sum(axis=0)
            v = v + dvs.sum(axis=0)
        eta = np.array([p[0], p[1], p[2], self.roll, self.pitch, self.psi])
        self.output = (eta, np.concatenate((r_now.T @ v, self.rates)))

    # -- reports -----------------------------------------------------------------------------------------------

    def variances(self) -> tuple[float, float, float, float]:
        """(velocity, horizontal position, height, compass) as EKF_STATUS_REPORT carries them: the square roots
        of the last test ratios (`NavEKF3_core::getVariances`)."""
        r = self.ratios
        return math.sqrt(r["vel"]), math.sqrt(r["pos"]), math.sqrt(r["hgt"]), math.sqrt(r["mag"])

    def position_std(self) -> float:
        """m: the horizontal position's standard deviation at the horizon."""
        return math.sqrt(max(self.P[0, 0], self.P[1, 1]))
