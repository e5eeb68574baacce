"""A simple battery: open-circuit voltage from the state of charge, minus an internal-resistance drop.

Shape of a 4S Li-ion pack (Blue Robotics 14.8 V, 18 Ah), scaled so that a full pack reads `full_voltage`. A failing
pack (a `battery=RATE@T` vehicle fault) sags `sag` volts more at its terminals (never below 0 V).
"""

from __future__ import annotations

from bisect import bisect_right

# Open-circuit voltage of a 4S Li-ion pack (V) against state of charge (0..1).
_SOC = (0.0, 0.05, 0.1, 0.2, 0.5, 0.8, 0.9, 1.0)
_OCV = (12.0, 13.2, 13.8, 14.4, 15.0, 15.8, 16.2, 16.8)
INTERNAL_RESISTANCE = 0.03      # ohm, whole pack
HOTEL_CURRENT = 0.5             # A drawn by the electronics (flight controller, companion, camera)


class Battery:
    """State of charge and terminal voltage; `step(thruster_current, dt)` drains it."""

    def __init__(self, full_voltage: float = 16.8, capacity_ah: float = 18.0):
        self.full_voltage = full_voltage
        self.capacity_ah = capacity_ah
        self.consumed_ah = 0.0
        self.current = HOTEL_CURRENT
        self.sag = 0.0
        self.voltage = self._terminal()

    @property
    def remaining(self) -> float:
        """State of charge, 0..1."""
        return min(max(1.0 - self.consumed_ah / self.capacity_ah, 0.0), 1.0)

    def step(self, thruster_current: float, dt: float) -> None:
        """Draw `thruster_current` A (plus the electronics) for `dt` s."""
        self.current = HOTEL_CURRENT + thruster_current
        self.consumed_ah += self.current * dt / 3600.0
        self.voltage = self._terminal()

    def set_sag(self, volts: float) -> None:
        """The fault's extra sag from now on, V."""
        if volts != self.sag:
            self.sag = volts
            self.voltage = self._terminal()

    def _terminal(self) -> float:
        ocv = _open_circuit(self.remaining) * self.full_voltage / _OCV[-1]
        return max(ocv - INTERNAL_RESISTANCE * self.current - self.sag, 0.0)


def _open_circuit(soc: float) -> float:
    """The pack's open-circuit voltage at state of charge `soc` (0..1), linear between the table's points (a scalar
    lookup every physics step: no array call)."""
    k = min(max(bisect_right(_SOC, soc), 1), len(_SOC) - 1)
    s0, s1, v0, v1 = _SOC[k - 1], _SOC[k], _OCV[k - 1], _OCV[k]
    return v0 + (v1 - v0) * (min(max(soc, s0), s1) - s0) / (s1 - s0)
