"""One control tick's record: what the runner computed and measured, for the run log and live telemetry."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class TickRecord:
    """Everything worth logging about one tick of the control loop (vehicle time t, SI units, NED/FRD)."""

    t: float                        # s, vehicle time since the mission started
    vehicle_time: float             # s, the state's time on the vehicle's clock (time_boot_ms), to align other logs
    eta: np.ndarray                 # (6,) measured pose
    nu: np.ndarray                  # (6,) measured body velocity
    reference: np.ndarray           # (18,) eta_d, eta_dot_d, eta_ddot_d
    tau: np.ndarray                 # (6,) commanded wrench (before allocation)
    tau_hat: np.ndarray             # (6,) disturbance estimate
    s: np.ndarray                   # (6,) sliding variable
    gamma: np.ndarray               # (6,) adaptation rates
    thrusts: np.ndarray             # (8,) allocated thrusts, N
    pwm: np.ndarray                 # (8,) commanded PWM, us
    progress: float                 # mission progress in [0, 1]
    telemetry_age: float            # s, age of the newest state sample when the command left
    latency: float                  # wall s from that sample's arrival to the command leaving
    control_rate: float             # Hz, achieved over the last second of vehicle time
    battery_voltage: float          # V
    horizon: float = 0.0            # s the state was predicted forward (measurement to when the command acts)
    true_disturbance: np.ndarray | None = None   # (6,) when known (simulation)
    truth: np.ndarray | None = None  # (3,) true NED position when a simulator says it (SIM_STATE), else None
    reported: np.ndarray | None = None   # (3,) the vehicle's own position estimate (eta's unless --estimator model)
    height: float = float("nan")    # m: the echo sounder's last range on an altitude or standoff leg
    height_true: float = float("nan")   # m: the true height above the leg's surface, when a simulator says it
    surface: float = float("nan")   # m: the estimated depth of the leg's surface (bottom or ice)
