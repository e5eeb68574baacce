"""The built-in vehicle's further sensors, beyond its navigation suite: each in one module of this package, named here
by its `navigation:` section. A new one is its module (its figures, what it measures from the truth and the world,
what it puts on the link) and its line in SENSORS.

A sensor module gives a class built from (its section's value, the bridge's seed, the environment's seafloor, its ice
ceiling) that raises NavigationError (one line) for figures it refuses, and has `next_event` (nothing is due before),
`sample(t, eta, nu)` (its readings on the link by vehicle time t) and `messages(reading, time_boot_ms)` (each
reading's (message, (sysid, compid)) pairs). They run whatever the navigation preset, ideal too, and through the
autopilot's reboots (they hang off the companion computer).
"""

from __future__ import annotations

from rov_mav.model.navigation import Navigation, NavigationError
from sim_bridge.navigation import echo_sounder

SENSORS = {echo_sounder.SECTION: echo_sounder.EchoSounder}


def attached_sensors(navigation: Navigation, seed: int, environment=None) -> list:
    """The sensors `navigation` names beyond its suite (NavigationError for a section no sensor reads)."""
    seafloor = getattr(environment, "seafloor", None)
    ice = getattr(environment, "ice", None)
    out = []
    for section, value in navigation.more.items():
        if section not in SENSORS:
            raise NavigationError(f"navigation: unknown section '{section}' (the built-in vehicle's sensors: imu, "
                                  f"compass, bar30, dvl, ugps, {', '.join(SENSORS)})")
        out.append(SENSORS[section](value, seed, seafloor, ice))
    return out
