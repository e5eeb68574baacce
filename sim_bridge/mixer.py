"""ArduSub's vectored_6dof motor mixer (BlueROV2 Heavy, FRAME_CONFIG 2): a table of factors and a loop over it.

Inputs are the pilot axes in [-1, 1] in the order (roll, pitch, yaw, throttle, forward, lateral). As in
AP_Motors6DOF, the vertical group (roll, pitch, throttle) and the horizontal group (yaw, forward, lateral) are each
scaled down together when one motor's sum exceeds 1, then added, multiplied by the motor's direction (+1/-1) and
clamped to [-1, 1]; PWM = 1500 + 400 * out, clamped to MOT_PWM_MIN..MAX.
"""

from __future__ import annotations

import numpy as np

# Factors per motor M1..M8: roll, pitch, yaw, throttle, forward, lateral (reference file, AP_Motors6DOF).
FACTORS = np.array([
    [0, 0, 1, 0, -1, 1],
    [0, 0, -1, 0, -1, -1],
    [0, 0, -1, 0, 1, 1],
    [0, 0, 1, 0, 1, -1],
    [1, -1, 0, -1, 0, 0],
    [-1, -1, 0, -1, 0, 0],
    [1, 1, 0, -1, 0, 0],
    [-1, 1, 0, -1, 0, 0],
], dtype=float)
_VERTICAL = [0, 1, 3]
_HORIZONTAL = [2, 4, 5]


def mix(axes: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Motor outputs (8,) in [-1, 1] from pilot axes (6,) and motor directions (8,) of +1/-1."""
    axes = np.asarray(axes, dtype=float)
    vertical = FACTORS[:, _VERTICAL] @ axes[_VERTICAL]
    horizontal = FACTORS[:, _HORIZONTAL] @ axes[_HORIZONTAL]
    vertical /= max(1.0, float(np.max(np.abs(vertical))))
    horizontal /= max(1.0, float(np.max(np.abs(horizontal))))
    return np.clip(directions * (vertical + horizontal), -1.0, 1.0)


def to_pwm(outputs: np.ndarray, pwm_min: float, pwm_max: float) -> np.ndarray:
    """PWM (8,) in us for motor outputs in [-1, 1]."""
    return np.clip(np.rint(1500.0 + 400.0 * np.asarray(outputs)), pwm_min, pwm_max).astype(np.int32)
