"""The law's position and velocity from the vehicle's estimate: a complementary filter that takes the motion the
reported velocity shows at once and the reported position's corrections slowly.

An estimator that corrects position and velocity from different sensors (ArduSub's EKF3: an acoustic fix or GPS for
one, the IMU or a DVL for the other) reports a position whose corrections come at the fixes' rate (3.8 Hz for an
acoustic system, each spread over EK3_TAU_OUTPUT, 0.25 s), and a velocity that is not quite that position's rate
(measured on ArduSub SITL: 2 cm/s over seconds). Fed to the law as they are, the corrections become thruster
activity (s = e_dot + k1 e differentiates them) and the bias holds the position error at -bias / k1. The blend:

    e = p - p_hat,   b' = L2 e,   v_hat = v + b + L1 e,   p_hat' = v_hat

p_hat follows the reported velocity at once and the reported position below L1 rad/s (a correction's 1-4 Hz content
reaches the law at about L1 / omega of its size); b learns a steady velocity bias over L1 / L2 s, so that p_hat
settles on p and v_hat on p's rate. L2 = L1^2 / 12.5 (damping 1.8: the integral removes a bias, it does not ring).
L1 = 0 passes both through unchanged.
"""

from __future__ import annotations

import numpy as np

MAX_STEP = 0.5          # s: a longer gap between samples (a stall, a lost link) restarts the filter at the position
BIAS_RATIO = 12.5       # L1^2 / L2


class EstimateBlend:
    """`update(t, position, velocity)` -> the law's (position, velocity), each (3,) NED; one call per state sample."""

    def __init__(self, bandwidth: float):
        if bandwidth < 0:
            raise ValueError(f"estimate blend bandwidth must be >= 0, got {bandwidth:g}")
        self.bandwidth = float(bandwidth)
        self._bias_gain = self.bandwidth ** 2 / BIAS_RATIO
        self._p_hat: np.ndarray | None = None
        self._t = 0.0
        self._v_hat = np.zeros(3)
        self.bias = np.zeros(3)          # m/s: the reported velocity less the reported position's rate, as learnt

    def update(self, t: float, position, velocity) -> tuple[np.ndarray, np.ndarray]:
        position = np.asarray(position, dtype=float)
        velocity = np.asarray(velocity, dtype=float)
        if self.bandwidth == 0.0:
            return position.copy(), velocity.copy()
        dt = t - self._t
        if self._p_hat is None or not 0.0 <= dt <= MAX_STEP:
            self._p_hat, self.bias = position.copy(), np.zeros(3)
        elif dt > 0.0:
            self._p_hat = self._p_hat + dt * self._v_hat
        else:
            return self._p_hat.copy(), self._v_hat.copy()      # the same sample again
        self._t = t
        e = position - self._p_hat
        self.bias = self.bias - self._bias_gain * e * dt
        self._v_hat = velocity - self.bias + self.bandwidth * e
        return self._p_hat.copy(), self._v_hat.copy()
