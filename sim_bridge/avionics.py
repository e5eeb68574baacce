"""What the autopilot reads from its sensors during one boot, under the vehicle's faults (`sim_bridge.vehicle_faults`).

- The depth sensor (Bar30): found at boot only if it has not failed yet (`ap.depth_sensor_present`); once failed it
  reads its last value on (AP_Baro keeps the last pressure; SCALED_PRESSURE2 goes on showing it).
- The navigation estimate (`sim_bridge.navigation`): the EKF of this boot, on the measured state and the position
  source.
- The battery monitor (AP_BattMonitor's analog backend): the pack's terminal voltage (with the fault's sag) and the
  charge counted from boot (a reboot starts it from 0 again), the share left of BATT_CAPACITY.
- The leak probe.
`sensors()` gathers them for the failsafes (`sim_bridge.failsafes.Sensors`).
"""

from __future__ import annotations

import numpy as np

from sim_bridge.battery import Battery
from sim_bridge.failsafes import Sensors
from sim_bridge.navigation import Navigation
from sim_bridge.vehicle_faults import LiveFaults


class Avionics:
    """The sensors of one boot, started at vehicle time t."""

    def __init__(self, live: LiveFaults, battery: Battery, t: float):
        self.live = live
        self.battery = battery
        self.depth_present = live.depth_sensor_ok(t)
        self.navigation = Navigation(live.navigation_ok(t))
        self.bar30: float | None = None           # m: the failed depth sensor's last reading (None: working)
        self._bar30_good: float | None = None
        self._consumed_at_boot = battery.consumed_ah

    def navigate(self, t: float, uptime: float, measured) -> tuple[np.ndarray, np.ndarray]:
        """The EKF's estimate at vehicle time t (uptime since boot) from the measured (eta, nu)."""
        depth_ok = self.live.depth_sensor_ok(t)
        if depth_ok:
            self.bar30, self._bar30_good = None, float(measured[0][2])
        elif self.bar30 is None:
            self.bar30 = self._bar30_good if self._bar30_good is not None else float(measured[0][2])
        return self.navigation.update(uptime, self.live.navigation_ok(t), depth_ok, measured)

    def consumed_ah(self) -> float:
        """The charge the monitor counted since boot."""
        return self.battery.consumed_ah - self._consumed_at_boot

    def remaining(self, capacity_mah: float) -> float:
        """The monitor's share left of BATT_CAPACITY (0..1)."""
        capacity = capacity_mah / 1000.0
        return min(max(1.0 - self.consumed_ah() / capacity, 0.0), 1.0) if capacity > 0 else 0.0

    def sensors(self, t: float, uptime: float) -> Sensors:
        velocity, _, _, compass = self.navigation.variances(uptime)
        return Sensors(leak=self.live.leaking(t), voltage=self.battery.voltage,
                       consumed_mah=self.consumed_ah() * 1000.0, velocity_variance=velocity,
                       compass_variance=compass, depth_healthy=self.live.depth_sensor_ok(t),
                       depth_present=self.depth_present)
