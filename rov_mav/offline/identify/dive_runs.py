"""A vehicle's own DataFlash log as identification data: its motors' outputs read through its frame, and, for a
pilot's dive (no mission, so no reference), the motion it excited and a reference made of the dive itself.

- Motors: motor k drives the outputs whose SERVOn_FUNCTION is 32 + k (SRV_Channel.h `get_motor_function`); the
  logged RCOU PWM already holds MOT_k_DIRECTION (AP_Motors6DOF::output_armed_stabilizing multiplies each motor's
  thrust by its direction before the PWM), so a thrust's sign is the PWM's times the direction.
- The reference: the logged pose smoothed over SMOOTHING s (a Savitzky-Golay fit, with its first and second
  derivatives), per stretch of armed states without a gap. It carries little of the sensors' noise, as a flown
  reference does, but it is the dive's own motion: the instruments are weaker than a mission's.
- Excitation: a DOF is fitted when its smoothed body velocity varies by at least EXCITED (RMS about its mean); surge
  and sway only when the log holds a horizontal velocity of its own (external navigation, VISP/VISV: a DVL): the
  EKF's horizontal velocity without one is an integral of accelerometer error.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import savgol_filter

from rov_mav.config import ConfigError
from rov_mav.model.dynamics import body_velocity
from rov_mav.model.frames import MOTOR_FUNCTION_BASE, Frame
from rov_mav.offline.identify.force_balance import gap_free

SMOOTHING = 1.0               # s, span of the reference's smoothing
MIN_STRETCH = 5.0             # s: armed stretches shorter than this are left out
EXCITED = np.array([0.05, 0.05, 0.05, np.radians(3.0), np.radians(3.0), np.radians(3.0)])   # m/s, rad/s RMS
DOFS = ("surge", "sway", "heave", "roll", "pitch", "yaw")
OUTPUTS = 16


@dataclass(frozen=True)
class Excitation:
    """One DOF of a dive: fitted or not, and why."""

    dof: str
    fitted: bool
    motion: float        # RMS of the smoothed body velocity about its mean, m/s or rad/s
    why: str


def motor_outputs(params: dict[str, float], frame: Frame) -> list[int]:
    """The 1-based output of each motor 1..n (SERVOn_FUNCTION = 32 + k); output k where the log holds none.
    ConfigError when a motor drives no output."""
    functions = {n: int(params[f"SERVO{n}_FUNCTION"]) for n in range(1, OUTPUTS + 1) if f"SERVO{n}_FUNCTION" in params}
    if not functions:
        return list(range(1, frame.motors + 1))
    out = []
    for k in range(1, frame.motors + 1):
        found = [n for n, f in functions.items() if f == MOTOR_FUNCTION_BASE + k]
        if not found:
            raise ConfigError(f"motor {k} of {frame.describe()} drives no output (no SERVOn_FUNCTION "
                              f"{MOTOR_FUNCTION_BASE + k} in the log)")
        out.append(found[0])
    return out


def motor_directions(params: dict[str, float], motors: int) -> np.ndarray:
    """(n,) MOT_k_DIRECTION, 1 where the log holds none."""
    return np.array([1.0 if params.get(f"MOT_{k}_DIRECTION", 1.0) >= 0 else -1.0 for k in range(1, motors + 1)])


def motor_pwm(servo: np.ndarray, outputs: list[int]) -> np.ndarray:
    """(M, n) the PWMs of the motors, from the logged outputs (M, 8 or more)."""
    if max(outputs) > servo.shape[1]:
        raise ConfigError(f"a motor drives SERVO{max(outputs)}, which the log does not record")
    return servo[:, [o - 1 for o in outputs]]


def own_reference(t: np.ndarray, eta: np.ndarray, span: float = SMOOTHING) -> np.ndarray:
    """(N, 18) the pose smoothed, its rate and acceleration (NED rates, Euler angle rates), per gap-free stretch;
    the heading unwrapped before smoothing."""
    out = np.empty((t.size, 18))
    unwrapped = eta.copy()
    for piece in gap_free(t):
        unwrapped[piece, 3:] = np.unwrap(eta[piece, 3:], axis=0)
        dt = float(np.median(np.diff(t[piece])))
        window = min(2 * int(round(span / dt / 2)) + 1, (piece.stop - piece.start) // 2 * 2 - 1)
        order = min(3, window - 1)
        for derivative in range(3):
            out[piece, 6 * derivative:6 * derivative + 6] = savgol_filter(
                unwrapped[piece], window, order, deriv=derivative, delta=dt, axis=0)
    return out


def excitation(reference: np.ndarray, horizontal_velocity: bool) -> list[Excitation]:
    """Per DOF, whether the dive moved it enough to fit (see the module docstring)."""
    nu = body_velocity(reference[:, :6], reference[:, 6:12])
    motion = np.std(nu, axis=0)
    out = []
    for i, dof in enumerate(DOFS):
        unit, scale = ("m/s", 1.0) if i < 3 else ("deg/s", np.degrees(1.0))
        if i < 2 and not horizontal_velocity:
            out.append(Excitation(dof, False, float(motion[i]), "no horizontal velocity in the log (no DVL: "
                                  "external navigation, VISP/VISV)"))
        elif motion[i] < EXCITED[i]:
            out.append(Excitation(dof, False, float(motion[i]), f"not excited: moved {motion[i] * scale:.3g} {unit} "
                                  f"RMS, below {EXCITED[i] * scale:.3g}"))
        else:
            out.append(Excitation(dof, True, float(motion[i]), f"excited: {motion[i] * scale:.3g} {unit} RMS"))
    return out
