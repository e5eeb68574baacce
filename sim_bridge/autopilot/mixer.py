"""ArduSub's 6-DOF motor mixer for the frame it booted with (`rov_mav.model.frames`): the pilot axes in, each motor's
output in [-1, 1] out, then PWM.

Inputs are the pilot axes in [-1, 1] in the order (roll, pitch, yaw, throttle, forward, lateral). The three paths of
`AP_Motors6DOF::output_armed_stabilizing` (libraries/AP_Motors/AP_Motors6DOF.cpp):
- GROUPED (VECTORED_6DOF, `output_armed_stabilizing_vectored_6dof`): the vertical group (roll, pitch, throttle) and
  the horizontal group (yaw, forward, lateral) each scaled down together when one motor's sum exceeds 1, then added;
- VECTORED (`output_armed_stabilizing_vectored`): summed, but on the horizontal thrusters that push the way the
  forward command asks (motors 1-2 for reverse, 3-4 for forward) the forward command is limited to
  1 - MOT_FV_CPLNG_K |throttle| (the forward/vertical coupling);
- SUMMED (the other frames): summed.
Each motor's sum is multiplied by its direction (MOT_n_DIRECTION, +1/-1) and clamped to [-1, 1]; PWM = 1500 + 400
out, clamped to MOT_PWM_MIN..MAX.
(The mix in plain Python floats: for 8 motors that is several times faster than numpy, and it runs every 2.5 ms.)
"""

from __future__ import annotations

import numpy as np

from rov_mav.model.frames import GROUPED, HEAVY, VECTORED, Frame

FV_COUPLING = 1.0                 # MOT_FV_CPLNG_K's default (range 0-1.5)
_FORWARD_SIDE = (-1, -1, 1, 1)    # VECTORED: the forward command's sign each horizontal motor 1-4 is limited on


def mix(axes, directions, frame: Frame = HEAVY, coupling: float = FV_COUPLING) -> np.ndarray:
    """Motor outputs (n,) in [-1, 1] of `frame`'s n motors from pilot axes (6,) and motor directions (>= n) of
    +1/-1."""
    roll, pitch, yaw, throttle, forward, lateral = (float(a) for a in axes)
    factors = frame.factors
    vertical = [f[0] * roll + f[1] * pitch + f[3] * throttle for f in factors]
    if frame.mixer == VECTORED:
        limit = max(0.0, 1.0 - coupling * abs(throttle))
        horizontal = [f[2] * yaw + f[4] * _coupled(forward, i, limit) + f[5] * lateral for i, f in enumerate(factors)]
    else:
        horizontal = [f[2] * yaw + f[4] * forward + f[5] * lateral for f in factors]
    if frame.mixer == GROUPED:
        v_scale = max(1.0, max(abs(x) for x in vertical))
        h_scale = max(1.0, max(abs(x) for x in horizontal))
    else:
        v_scale = h_scale = 1.0
    return np.array([min(max(d * (v / v_scale + h / h_scale), -1.0), 1.0)
                     for d, v, h in zip(directions, vertical, horizontal)])


def _coupled(forward: float, motor: int, limit: float) -> float:
    """The forward command motor `motor` (0-based) takes on the VECTORED frame."""
    side = _FORWARD_SIDE[motor] if motor < len(_FORWARD_SIDE) else 0
    if forward != 0.0 and side * forward > 0.0:
        return min(max(forward, -limit), limit)
    return forward


def to_pwm(outputs, pwm_min: float, pwm_max: float) -> np.ndarray:
    """PWM (n,) in us for motor outputs in [-1, 1]."""
    pwm = np.rint(1500.0 + 400.0 * np.asarray(outputs, dtype=float))      # half to even, as round()
    return np.minimum(np.maximum(pwm, pwm_min), pwm_max).astype(np.int32)
