"""Attitude, depth and position holding for ArduSub's assisted modes, as simple PD loops on the vehicle's state.

Stand-ins for ArduSub's cascaded controllers, with the same division of labour (gains are this bridge's own):
- STABILIZE: roll and pitch sticks command lean angles (level when centred), the yaw stick a yaw rate (heading held
  when centred); throttle, forward and lateral pass straight to the mixer.
- ACRO: roll, pitch and yaw sticks command body rates.
- ALT_HOLD: as STABILIZE, and depth held while the throttle stick is centred (a climb rate otherwise).
- POSHOLD: as ALT_HOLD, and horizontal position held while the forward and lateral sticks are centred; without a
  position estimate the forward and lateral sticks pass straight through (`ModePoshold::control_horizontal`).
- SURFACE: as ALT_HOLD with the depth target rising at a given climb rate whatever the throttle stick, at most
  LEASH above the vehicle (a stand-in for the position controller's limited error) (`sim_bridge.modes.surface`).
All work in the mixer's normalised axes (roll, pitch, yaw, throttle, forward, lateral), each clamped to [-1, 1].
"""

from __future__ import annotations

import math

import numpy as np

from rov_mav.units import wrap_angle

STABILIZE, ACRO, ALT_HOLD, SURFACE, POSHOLD = 0, 1, 2, 9, 16
ASSISTED = frozenset({STABILIZE, ACRO, ALT_HOLD, SURFACE, POSHOLD})
DEPTH_HOLDING = frozenset({ALT_HOLD, SURFACE, POSHOLD})
DEAD_ZONE = 0.05               # stick deflection (of 1) treated as centred
MAX_LEAN = math.radians(45)    # rad at full roll/pitch stick
MAX_RATE = math.radians(90)    # rad/s at full stick (yaw in STABILIZE, all axes in ACRO)
MAX_CLIMB = 0.5                # m/s at full throttle stick
ANGLE_P, RATE_D = 3.0, 0.3     # per rad, per rad/s
RATE_P = 0.9                   # per rad/s of body-rate error (rate commands)
DEPTH_P, DEPTH_I, DEPTH_D = 0.5, 0.2, 0.5              # per m, per m s, per m/s
POSITION_P, POSITION_I, POSITION_D = 0.3, 0.05, 0.5
INTEGRAL_LIMIT = 0.3           # largest share of an axis the integrators may hold
LEASH = 1.0                    # m: how far a climbing depth target may lead the vehicle


def _clamp(a: float) -> float:
    return min(max(float(a), -1.0), 1.0)



class Holds:
    """The targets being held (heading, depth, position) and the loops that hold them."""

    def __init__(self):
        self.reset()

    def reset(self) -> None:
        """Forget the targets (on a mode change or when disarmed): the next step captures the current state."""
        self.heading: float | None = None
        self.lean: tuple[float, float] | None = None   # roll and pitch targets (rad) while angles are held
        self.depth: float | None = None
        self.position: tuple[float, float] | None = None
        self.depth_integral = 0.0
        self.integral = [0.0, 0.0]                   # of the position error, body axes

    def axes(self, mode: int, pilot, eta: np.ndarray, nu: np.ndarray, dt: float, climb: float = 0.0,
             min_depth: float | None = None, position_ok: bool = True) -> list[float]:
        """Mixer axes (6,) for `mode` from the pilot's axes (6,) and the vehicle's eta, nu (6,); SURFACE's `climb`
        (m/s up), the shallowest depth target allowed (m), whether there is a position to hold."""
        roll, pitch, yaw, throttle, forward, lateral = (float(a) for a in pilot)
        phi, theta, psi = eta[3:6]
        p, q, r = nu[3:6]
        if mode == ACRO:
            self.lean = None
            out = [RATE_P * (roll * MAX_RATE - p), RATE_P * (pitch * MAX_RATE - q), RATE_P * (yaw * MAX_RATE - r),
                   throttle, forward, lateral]
            return [_clamp(a) for a in out]
        self.lean = (roll * MAX_LEAN, pitch * MAX_LEAN)
        out = [ANGLE_P * (self.lean[0] - phi) - RATE_D * p, ANGLE_P * (self.lean[1] - theta) - RATE_D * q,
               0.0, throttle, forward, lateral]
        if abs(yaw) > DEAD_ZONE or self.heading is None:
            self.heading = float(psi)
            out[2] = RATE_P * (yaw * MAX_RATE - r)
        else:
            out[2] = ANGLE_P * wrap_angle(self.heading - psi) - RATE_D * r
        if mode in DEPTH_HOLDING:
            out[3] = self._depth(throttle, eta, nu, dt, climb if mode == SURFACE else None, min_depth)
        if mode == POSHOLD and position_ok:
            out[4], out[5] = self._position(forward, lateral, eta, nu, dt)
        elif mode == POSHOLD:
            self.position = None
        return [_clamp(a) for a in out]

    def targets(self) -> tuple[float, float, float, float]:
        """(roll, pitch, yaw rad, depth m) held now, NaN for each not held: what ArduSub logs as ATT's DesRoll,
        DesPitch, DesYaw and CTUN's DAlt (`Sub::Log_Write_Attitude`, `Sub::Log_Write_Control_Tuning`)."""
        nan = math.nan
        roll, pitch = self.lean if self.lean is not None else (nan, nan)
        return (roll, pitch, nan if self.lean is None or self.heading is None else self.heading,
                nan if self.depth is None else self.depth)

    def _depth(self, throttle: float, eta: np.ndarray, nu: np.ndarray, dt: float, climb: float | None = None,
               min_depth: float | None = None) -> float:
        """Throttle axis (up positive) holding or moving the depth target; eta[2] and the target are depths."""
        if self.depth is None:
            self.depth = float(eta[2])
        if climb is not None:
            self.depth = max(self.depth - climb * dt, float(eta[2]) - LEASH)
        elif abs(throttle) > DEAD_ZONE:
            self.depth -= throttle * MAX_CLIMB * dt
        if min_depth is not None:
            self.depth = max(self.depth, min_depth)
        error = self.depth - float(eta[2])
        self.depth_integral = min(max(self.depth_integral + DEPTH_I * error * dt, -INTEGRAL_LIMIT), INTEGRAL_LIMIT)
        cf, sf, ct, st = math.cos(eta[3]), math.sin(eta[3]), math.cos(eta[4]), math.sin(eta[4])
        z_rate = -st * nu[0] + ct * sf * nu[1] + ct * cf * nu[2]          # down, NED
        return -(DEPTH_P * error + self.depth_integral - DEPTH_D * z_rate)

    def _position(self, forward: float, lateral: float, eta: np.ndarray, nu: np.ndarray, dt: float):
        """Forward and lateral axes: the pilot's when deflected, else holding the horizontal position."""
        if abs(forward) > DEAD_ZONE or abs(lateral) > DEAD_ZONE or self.position is None:
            self.position = (float(eta[0]), float(eta[1]))
            return forward, lateral
        c, s = math.cos(eta[5]), math.sin(eta[5])
        north, east = self.position[0] - eta[0], self.position[1] - eta[1]
        error = (c * north + s * east, -s * north + c * east)          # in the body axes
        self.integral = [min(max(i + POSITION_I * e * dt, -INTEGRAL_LIMIT), INTEGRAL_LIMIT)
                         for i, e in zip(self.integral, error)]
        return tuple(POSITION_P * e + i - POSITION_D * v for e, i, v in zip(error, self.integral, nu[:2]))
