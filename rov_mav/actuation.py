"""The runner's actuation: wrench -> 8 thrusts -> 8 PWMs, at the battery voltage, within the thrust cap.

One allocator and one T200 map for the project (`rov_mav.thrusters`); this only keeps their limits current: each
thruster's range is the T200's at the measured battery voltage, capped at `max_thrust` N both ways.
"""

from __future__ import annotations

import numpy as np

from rov_mav.thrusters import Allocator, AllocationInfo, allocation_matrix, load_t200, thrusts_to_pwms
from rov_mav.vehicle import Vehicle

VOLTAGE_STEP = 0.1        # V: rebuild the allocator when the battery moved this much
DEFAULT_VOLTAGE = 16.0    # V: until the vehicle reports one (a charged 4S pack under load)


class Actuation:
    """`command(tau)` -> (thrusts (8,) N, PWMs (8,) us rounded, AllocationInfo)."""

    def __init__(self, vehicle: Vehicle, max_thrust: float | None = None, voltage: float = DEFAULT_VOLTAGE):
        self.matrix = allocation_matrix(vehicle.thruster_positions, vehicle.thruster_directions)
        self.max_thrust = max_thrust
        self.t200 = load_t200()
        self.voltage = float("nan")
        self.allocator: Allocator | None = None
        self.set_voltage(voltage)

    def set_voltage(self, voltage: float) -> None:
        if abs(voltage - self.voltage) < VOLTAGE_STEP:
            return
        self.voltage = float(voltage)
        cap = np.inf if self.max_thrust is None else self.max_thrust
        n = self.matrix.shape[1]
        self.allocator = Allocator(self.matrix, np.full(n, -min(self.t200.max_reverse(voltage), cap)),
                                   np.full(n, min(self.t200.max_forward(voltage), cap)))

    def command(self, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray, AllocationInfo]:
        thrusts, info = self.allocator.thrusts(tau)
        return thrusts, np.round(thrusts_to_pwms(thrusts, self.voltage, self.t200)), info

    def thrust_of(self, pwms: np.ndarray) -> np.ndarray:
        """Thrusts (8,) N the vehicle produces at PWMs (8,) at the current voltage (the T200 map forward)."""
        return self.t200.thrust(pwms, self.voltage)
