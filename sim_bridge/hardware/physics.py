"""The simulated vehicle's hardware: 8 PWM -> thrust at the battery voltage (the vehicle file's thruster map: the T200
data, or a quadratic law) -> first-order lag -> body wrench tau = B f -> the shared 6-DOF plant; the battery is
drained by the thrusters' current.

Thruster faults (`rov_mav.model.vehicle_faults`, `thruster_effect(t)` at the step's vehicle time): a stuck ESC takes
its stuck PWM whatever it is sent (even no pulse); the thrust is multiplied by the thruster's gain: 0 for a dead one
(which draws no current either), K for a weak one, -1 for a reversed one (these two draw what they are told).
"""

from __future__ import annotations

import math

import numpy as np

from rov_mav.model.frames import MOTOR_FUNCTION_BASE
from rov_mav.model.thrusters import ThrusterMap, allocation_matrix
from rov_mav.model.vehicle import Vehicle
from rov_mav.model.vehicle_faults import VehicleFaults
from sim_bridge.hardware.battery import Battery

VOLTAGE_RESOLUTION = 0.01       # V: the T200 map is looked up at the battery voltage rounded to this
NO_PULSE_BELOW = 800            # us: an output this low (0 = unassigned) sends no pulse: the ESC stops


class Harness:
    """Which output each thruster's ESC is plugged into: thruster k where the vehicle was set up to drive motor k (the
    first output whose SERVOn_FUNCTION was 32 + k when the bridge started; the wires do not move when a parameter
    changes later). A thruster no output was set up to drive is not plugged in: no pulse, no thrust."""

    def __init__(self, functions: list[int], thrusters: int):
        self.wires = np.array([next((j for j, f in enumerate(functions) if f == MOTOR_FUNCTION_BASE + k), -1)
                               for k in range(1, thrusters + 1)])     # 0-based output, -1: none
        self._straight = bool(np.array_equal(self.wires, np.arange(thrusters)))   # thruster k on output k

    def pwm(self, outputs: np.ndarray) -> np.ndarray:
        """The PWM (n,) each thruster receives from the vehicle's outputs (16,) (0: none)."""
        if self._straight:
            return outputs[:len(self.wires)]
        return np.where(self.wires >= 0, outputs[np.maximum(self.wires, 0)], 0)


class Physics:
    """Advances `plant` (the shared rov_mav Plant) by fixed steps of `h` s under 8 thruster PWMs."""

    def __init__(self, vehicle: Vehicle, plant, battery: Battery, t200: ThrusterMap, h: float,
                 faults: VehicleFaults | None = None):
        self.plant = plant
        self.faults = faults if faults is not None and faults.thrusters else None
        self._changes = list(faults.thruster_times()) if self.faults is not None else []
        self._gain = np.ones(8)
        self._stuck = np.full(8, np.nan)
        self.battery = battery
        self.t200 = t200
        self.h = h
        self.matrix = allocation_matrix(vehicle.thruster_positions, vehicle.thruster_directions)
        tc = vehicle.thruster_time_constant
        self._lag = 1.0 if tc <= 0 else 1.0 - math.exp(-h / tc)
        self.thrusts = np.zeros(8)
        self.tau = np.zeros(6)
        self._key: tuple | None = None
        self._commanded = np.zeros(8)
        self._current = 0.0

    def step(self, pwm: np.ndarray, t: float = 0.0) -> None:
        """One step of h seconds with thruster PWMs (8,) in us held, from vehicle time t (for the faults)."""
        changed = False
        while self._changes and t >= self._changes[0]:
            self._changes.pop(0)
            self._gain, self._stuck = self.faults.thruster_effect(t)
            changed = True
        voltage = round(self.battery.voltage / VOLTAGE_RESOLUTION) * VOLTAGE_RESOLUTION
        key = (pwm.tobytes(), voltage)
        if key != self._key or changed:         # the T200 map only when the PWMs, voltage or faults changed
            self._key = key
            pulses = np.where(pwm < NO_PULSE_BELOW, 1500, pwm).astype(float)
            pulses = np.where(np.isnan(self._stuck), pulses, self._stuck)
            self._commanded = self.t200.thrust(pulses, voltage) * self._gain
            self._current = float(np.sum(self.t200.current(pulses, voltage) * (self._gain != 0)))
        self.thrusts += (self._commanded - self.thrusts) * self._lag
        self.tau = self.matrix @ self.thrusts
        self.plant.step(self.tau, self.h)
        self.battery.step(self._current, self.h)
