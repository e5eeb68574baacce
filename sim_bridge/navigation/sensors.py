"""The built-in vehicle's sensors, drawn from the plant's true state (`rov_mav.model.navigation` gives the figures).

Each sensor has its own random stream, seeded by the bridge's --seed and the sensor's index, so a run is reproducible
and adding a source does not change another's draws. `Sensors.sample(t, eta, nu, ...)` is called every physics step
and does work only when a sensor is due; it returns what reaches the autopilot by t:
- `ImuSample` at the IMU rate: the delta velocity over the interval in body axes (the inertial part: the sensor's
  gravity is taken as known), the body rates with a gyro bias about the vertical, and the AHRS's roll and pitch
  (truth plus a slowly varying tilt error, a first-order Gauss-Markov process with a 30 s time constant);
- `CompassSample` (heading plus bias and noise), `Bar30Sample` (depth plus noise; none once the sensor has failed);
- `DvlReport`: bottom-track body velocity with a scale error, a bias and noise, delivered `latency` after its ping,
  none while bottom lock is lost (the BlueOS DVL extension drops invalid reports, `dvl.py` `handle_velocity`) or the
  position source is lost (the navigation-lost fault);
- `UgpsFix`: the north/east position with noise growing with the slant range from the topside transceiver, an
  occasional outlier, `latency` late; in a dropout (or under the navigation-lost fault) the fix is invalid, as the
  UGPS extension still sends GPS_INPUT then, with fix_type 0 (`mavlink2resthelper.py` `send_gps_input`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rov_mav.model.dynamics import attitude_rotation
from rov_mav.model.navigation import Navigation

TILT_TAU = 30.0                   # s: the AHRS tilt error's correlation time (chosen)
EPS = 1e-9


@dataclass
class ImuSample:
    t: float
    dt: float
    dv_body: np.ndarray            # m/s over the interval, body axes
    gyro: np.ndarray               # rad/s, body axes
    roll: float                    # rad, the AHRS's
    pitch: float


@dataclass
class CompassSample:
    t: float
    heading: float                 # rad


@dataclass
class Bar30Sample:
    t: float
    depth: float                   # m


@dataclass
class DvlReport:
    t: float                       # s: time of validity (the ping)
    arrival: float                 # s: when the autopilot (and the link) has it
    velocity: np.ndarray           # m/s, body axes
    dt: float                      # s since the previous report
    fom: float                     # m/s: the DVL's figure of merit


@dataclass
class UgpsFix:
    t: float
    arrival: float
    north: float
    east: float
    std: float                     # m: the accuracy the system reports
    valid: bool


class _Every:
    """A periodic sensor on the physics clock: due at 0, 1/rate, 2/rate, ... (rounded to steps by the caller)."""

    def __init__(self, rate: float):
        self.period = 1.0 / rate
        self.next = 0.0
        self.last: float | None = None

    def due(self, t: float) -> bool:
        if t + EPS < self.next:
            return False
        self.next += self.period
        if self.next <= t + EPS:            # never pile up
            self.next = t + self.period
        return True


class Sensors:
    """The sensor suite of one vehicle (it runs on through the autopilot's reboots)."""

    def __init__(self, nav: Navigation, seed: int, eta: np.ndarray, nu: np.ndarray):
        self.nav = nav
        rngs = [np.random.default_rng(np.random.SeedSequence([seed, 20, k])) for k in range(6)]
        self._rng_imu, self._rng_compass, self._rng_bar30, self._rng_dvl, self._rng_ugps, self._rng_tilt = rngs
        self._imu, self._compass, self._bar30 = _Every(nav.imu.rate), _Every(nav.compass.rate), _Every(nav.bar30.rate)
        self._dvl = _Every(nav.dvl.rate) if nav.dvl else None
        self._ugps = _Every(nav.ugps.rate) if nav.ugps else None
        self._v_prev = attitude_rotation(*eta[3:6]) @ nu[:3]
        self._t_imu: float | None = None
        self._tilt = np.zeros(2)
        self._lock_lost_until = -math.inf
        self._dvl_last: float | None = None
        self._dropout_until = -math.inf
        self._pending: list = []           # DVL reports and fixes on their way, in arrival order
        self.next_event = 0.0              # s: nothing is due before (the caller may skip `sample` until then)

    def sample(self, t: float, eta: np.ndarray, nu: np.ndarray, source_ok: bool = True,
               depth_ok: bool = True) -> list:
        out = []
        if self._imu.due(t):
            out.append(self._imu_sample(t, eta, nu))
        if self._compass.due(t):
            c = self.nav.compass
            out.append(CompassSample(t, float(eta[5]) + c.bias + c.noise * self._rng_compass.standard_normal()))
        if self._bar30.due(t):
            noise = self.nav.bar30.noise * self._rng_bar30.standard_normal()
            if depth_ok:
                out.append(Bar30Sample(t, float(eta[2]) + noise))
        if self._dvl is not None and self._dvl.due(t):
            self._dvl_report(t, nu, source_ok)
        if self._ugps is not None and self._ugps.due(t):
            self._ugps_fix(t, eta, source_ok)
        while self._pending and self._pending[0].arrival <= t + EPS:
            out.append(self._pending.pop(0))
        self.next_event = min([e.next for e in (self._imu, self._compass, self._bar30, self._dvl, self._ugps)
                               if e is not None] + [p.arrival for p in self._pending[:1]])
        return out

    def _imu_sample(self, t: float, eta: np.ndarray, nu: np.ndarray) -> ImuSample:
        imu = self.nav.imu
        r = attitude_rotation(eta[3], eta[4], eta[5])
        v = r @ nu[:3]
        dt = t - self._t_imu if self._t_imu is not None else 1.0 / imu.rate
        dv_body = r.T @ (v - self._v_prev) + imu.accel_noise * dt * self._rng_imu.standard_normal(3)
        gyro = np.array(nu[3:6], dtype=float) + imu.gyro_noise * self._rng_imu.standard_normal(3)
        gyro[2] += imu.gyro_bias
        a = math.exp(-dt / TILT_TAU)
        self._tilt = a * self._tilt + math.sqrt(1 - a * a) * imu.tilt_error * self._rng_tilt.standard_normal(2)
        self._v_prev, self._t_imu = v, t
        return ImuSample(t, dt, dv_body, gyro, float(eta[3] + self._tilt[0]), float(eta[4] + self._tilt[1]))

    def _dvl_report(self, t: float, nu: np.ndarray, source_ok: bool) -> None:
        d, rng = self.nav.dvl, self._rng_dvl
        noise = d.noise * rng.standard_normal(3)
        lose = rng.random() < d.lock_loss_rate / d.rate
        span = rng.exponential(d.lock_loss_duration)
        if t >= self._lock_lost_until and lose:
            self._lock_lost_until = t + span
        dt = t - self._dvl_last if self._dvl_last is not None else 1.0 / d.rate
        self._dvl_last = t
        if t < self._lock_lost_until or not source_ok:
            return
        velocity = (1.0 + d.scale_error) * np.asarray(nu[:3], dtype=float) + d.bias + noise
        self._queue(DvlReport(t, t + d.latency, velocity, dt, d.noise))

    def _ugps_fix(self, t: float, eta: np.ndarray, source_ok: bool) -> None:
        u, rng = self.nav.ugps, self._rng_ugps
        draws = rng.standard_normal(4)
        outlier, start_dropout = rng.random() < u.outlier_probability, rng.random() < u.dropout_probability
        span = rng.exponential(u.dropout_duration)
        if t >= self._dropout_until and start_dropout:
            self._dropout_until = t + span
        slant = math.dist(eta[:3], u.transceiver)
        std = u.noise + u.noise_per_range * slant
        error = std * draws[:2] + (u.outlier_size * draws[2:] if outlier else 0.0)
        valid = source_ok and t >= self._dropout_until
        self._queue(UgpsFix(t, t + u.latency, float(eta[0] + error[0]), float(eta[1] + error[1]), std, valid))

    def _queue(self, item) -> None:
        self._pending.append(item)
        self._pending.sort(key=lambda x: x.arrival)
