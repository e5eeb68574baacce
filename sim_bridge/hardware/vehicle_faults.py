"""Which of the vehicle's faults (`rov_mav.model.vehicle_faults`) strike the built-in vehicle at a vehicle time.

The faults come from `BridgeConfig.vehicle_faults`, else from the environment's `vehicle_faults`, else none. Every
time is vehicle seconds since the bridge started (the physics clock, which runs on through reboots; the autopilot's
time since boot restarts at each). Thruster faults act in `sim_bridge.hardware.physics`; the others reach the autopilot
through what it reads (`sensors`): the leak probe, the pack's voltage, the position source
(`sim_bridge.navigation.aiding`),
the depth sensor (present at boot only if it has not failed yet); `reboot_due` tells the bridge when to cut the
power (`sim_bridge.hardware.boot`).
"""

from __future__ import annotations

from rov_mav.model.vehicle_faults import VehicleFaults


def resolve(explicit: VehicleFaults | None, environment) -> VehicleFaults:
    """The faults a bridge applies: `explicit` if given, else its environment's, else none."""
    if explicit is not None:
        return explicit
    return getattr(environment, "vehicle_faults", None) or VehicleFaults()


class LiveFaults:
    """The faults of one bridge run, asked at vehicle time t."""

    def __init__(self, faults: VehicleFaults):
        self.faults = faults
        self._reboots = sorted(faults.reboots)

    def reboot_due(self, t: float) -> bool:
        """True once when t reaches a `reboot@T` (several at once count once)."""
        due = False
        while self._reboots and t >= self._reboots[0]:
            self._reboots.pop(0)
            due = True
        return due

    def leaking(self, t: float) -> bool:
        return self.faults.leaking(t)

    def battery_sag(self, t: float) -> float:
        return self.faults.battery_sag(t)

    def navigation_ok(self, t: float) -> bool:
        return self.faults.navigation_ok(t)

    def depth_sensor_ok(self, t: float) -> bool:
        return self.faults.depth_sensor_ok(t)

    def navigation_offset(self, t: float):
        return self.faults.navigation_offset(t)
