"""Which of the vehicle's faults (`rov_mav.model.vehicle_faults`) strike the built-in vehicle at a vehicle time.

The faults come from `BridgeConfig.vehicle_faults`, else from the environment's `vehicle_faults`, else none. Every
time is vehicle seconds since the bridge started (the physics clock, which runs on through reboots; the autopilot's
time since boot restarts at each). Thruster faults act in `sim_bridge.hardware.physics`; the others reach the autopilot
through what it reads (`sim_bridge.navigation.avionics`): the leak probe, the pack's voltage, the position source
(`sim_bridge.navigation.aiding`),
the depth sensor (present at boot only if it has not failed yet); `RebootSchedule` tells the bridge when to cut the
power (`sim_bridge.hardware.boot`).
"""

from __future__ import annotations

from rov_mav.model.vehicle_faults import VehicleFaults


def resolve(explicit: VehicleFaults | None, environment) -> VehicleFaults:
    """The faults a bridge applies: `explicit` if given, else its environment's, else none."""
    if explicit is not None:
        return explicit
    return getattr(environment, "vehicle_faults", None) or VehicleFaults()


class RebootSchedule:
    """When the bridge cuts the power for a `reboot@T` fault; the vehicle's other faults are asked of
    `VehicleFaults` itself at a vehicle time."""

    def __init__(self, faults: VehicleFaults):
        self._reboots = sorted(faults.reboots)

    def due(self, t: float) -> bool:
        """True once when t reaches a `reboot@T` (several at once count once)."""
        due = False
        while self._reboots and t >= self._reboots[0]:
            self._reboots.pop(0)
            due = True
        return due
