"""The vehicle's NED velocity made consistent with its NED position, for the law's error rate.

An estimator that corrects position and velocity from different sensors (ArduSub's EKF3: GPS, USBL or a position
fix for one, the IMU, a DVL or GPS velocity for the other) reports a velocity that is not the rate of the position it
reports: measured on ArduSub SITL, they disagree by about 2 cm/s over seconds. The law's s = e_dot + k1 e then holds
the position error at -bias / k1 (2 cm with the report's k1 = 1 s^-1 in y). A complementary filter removes it:

    v_hat = v + L (p - p_hat),   p_hat' = v_hat

so v_hat is the reported velocity above L rad/s and the rate of the reported position below it. L = 0 passes the
velocity through unchanged.
"""

from __future__ import annotations

import numpy as np

MAX_STEP = 0.5          # s: a longer gap between samples (a stall, a lost link) restarts the filter at the position


class VelocityBlend:
    """`update(t, position, velocity)` -> the blended velocity (3,), one call per state sample."""

    def __init__(self, bandwidth: float):
        if bandwidth < 0:
            raise ValueError(f"velocity blend bandwidth must be >= 0, got {bandwidth:g}")
        self.bandwidth = float(bandwidth)
        self._p_hat: np.ndarray | None = None
        self._t = 0.0
        self._v_hat = np.zeros(3)

    def update(self, t: float, position: np.ndarray, velocity: np.ndarray) -> np.ndarray:
        position = np.asarray(position, dtype=float)
        velocity = np.asarray(velocity, dtype=float)
        if self.bandwidth == 0.0:
            return velocity
        dt = t - self._t
        if self._p_hat is None or not 0.0 <= dt <= MAX_STEP:
            self._p_hat = position.copy()
        elif dt > 0.0:
            self._p_hat = self._p_hat + dt * self._v_hat
        else:
            return self._v_hat.copy()               # the same sample again
        self._t = t
        self._v_hat = velocity + self.bandwidth * (position - self._p_hat)
        return self._v_hat.copy()
