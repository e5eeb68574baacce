"""What the autopilot reads from its sensors during one boot, under the vehicle's faults
(`rov_mav.model.vehicle_faults`).

- The depth sensor (Bar30): found at boot only if it has not failed yet (`ap.depth_sensor_present`); once failed it
  reads its last value on (AP_Baro keeps the last pressure; SCALED_PRESSURE2 goes on showing it).
- The navigation estimate (`sim_bridge.navigation.aiding`): the EKF of this boot, on the measured state and the position
  source; with a navigation other than `ideal` (`rov_mav.model.navigation`), on the estimate of this boot's
  estimator (`sim_bridge.navigation.estimator`) fed with the sensors' samples (`feed`), the position source counting as
  lost
  AID_GAP after the estimator last fused a DVL velocity or an acoustic fix; EKF_STATUS_REPORT's variances are then
  the estimator's test ratios (growing as `sim_bridge.navigation.aiding` says while the source is lost) and its flags
  gain
  GPS glitching (bit 15) while acoustic fixes are rejected.
- The battery monitor (AP_BattMonitor's analog backend): the pack's terminal voltage (with the fault's sag) and the
  charge counted from boot (a reboot starts it from 0 again), the share left of BATT_CAPACITY.
- A navigation reset (`navigation-reset=N/E@T`): the estimate's position moved by (N, E) from T on and left there, as
  after a DVL's "set position" (a VISION_POSITION_ESTIMATE with its reset_counter stepped: `AP_VisualOdom_MAV`); on
  acoustic fixes a real EKF would then be pulled back by the fixes, this one is not (the worst case for a run).
- The leak probe.
`sensors()` gathers them for the failsafes (`sim_bridge.autopilot.failsafes.Readings`).
"""

from __future__ import annotations

import numpy as np

from rov_mav.model.navigation import Navigation
from rov_mav.model.vehicle_faults import VehicleFaults
from sim_bridge.hardware.battery import Battery
from sim_bridge.navigation.estimator import Estimator
from sim_bridge.autopilot.failsafes import Readings
from sim_bridge.navigation.aiding import Aiding


AID_GAP = 1.0                   # s without a fused DVL velocity or fix before the source counts as lost (chosen)
GPS_GLITCHING = 1 << 15         # EKF_STATUS_REPORT flag


class Avionics:
    """The sensors of one boot, started at vehicle time t (with `nav` other than ideal, an estimator initialised
    on `state`, the plant's (eta, nu) at boot)."""

    def __init__(self, faults: VehicleFaults, battery: Battery, t: float, nav: Navigation | None = None,
                 state=None):
        self.faults = faults
        self.battery = battery
        self.depth_present = faults.depth_sensor_ok(t)
        self.nav = nav
        self.estimator = Estimator(nav, t, *state) if nav is not None and not nav.ideal else None
        has_source = self.estimator is None or nav.has_position_source
        self.navigation = Aiding(faults.navigation_ok(t) and has_source)
        self.bar30: float | None = None           # m: the failed depth sensor's last reading (None: working)
        self._bar30_good: float | None = None
        self._consumed_at_boot = battery.consumed_ah

    def navigate(self, t: float, uptime: float, measured) -> tuple[np.ndarray, np.ndarray]:
        """The EKF's estimate at vehicle time t (uptime since boot) from the measured (eta, nu)."""
        depth_ok = self.faults.depth_sensor_ok(t)
        if depth_ok:
            self.bar30, self._bar30_good = None, float(measured[0][2])
        elif self.bar30 is None:
            self.bar30 = self._bar30_good if self._bar30_good is not None else float(measured[0][2])
        source_ok = self.faults.navigation_ok(t)
        if self.estimator is not None:
            measured = self.estimator.output
            source_ok = source_ok and self.nav.has_position_source and t - self.estimator.aided_at < AID_GAP
        eta, nu = self.navigation.update(uptime, source_ok, depth_ok, measured)
        offset = self.faults.navigation_offset(t)
        if offset.any():
            eta = eta.copy()
            eta[:3] += offset
        return eta, nu

    def feed(self, items: list) -> None:
        """The sensors' samples that reached the autopilot (navigations other than ideal)."""
        for item in items:
            self.estimator.feed(item)

    def variances(self, uptime: float) -> tuple[float, float, float, float]:
        """EKF_STATUS_REPORT's (velocity, horizontal position, height, compass)."""
        grown = self.navigation.variances(uptime)
        if self.estimator is None:
            return grown
        own = self.estimator.variances()
        if self.navigation.lost_since is None:
            return own
        return max(own[0], grown[0]), max(own[1], grown[1]), own[2], own[3]

    def flags(self, uptime: float) -> int:
        flags = self.navigation.flags(uptime)
        if self.estimator is not None and self.estimator.glitching:
            flags |= GPS_GLITCHING
        return flags

    def consumed_ah(self) -> float:
        """The charge the monitor counted since boot."""
        return self.battery.consumed_ah - self._consumed_at_boot

    def remaining(self, capacity_mah: float) -> float:
        """The monitor's share left of BATT_CAPACITY (0..1)."""
        capacity = capacity_mah / 1000.0
        return min(max(1.0 - self.consumed_ah() / capacity, 0.0), 1.0) if capacity > 0 else 0.0

    def sensors(self, t: float, uptime: float) -> Readings:
        velocity, _, _, compass = self.variances(uptime)
        return Readings(leak=self.faults.leaking(t), voltage=self.battery.voltage,
                       consumed_mah=self.consumed_ah() * 1000.0, velocity_variance=velocity,
                       compass_variance=compass, depth_healthy=self.faults.depth_sensor_ok(t),
                       depth_present=self.depth_present)
