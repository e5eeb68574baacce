"""ArduSub's arming checks on the built-in vehicle.

`GCS_MAVLINK::handle_command_component_arm_disarm` (libraries/GCS_MAVLink/GCS_Common.cpp) arms through
`AP_Arming::arm` (libraries/AP_Arming/AP_Arming.cpp), which runs the pre-arm and arm checks unless param2 is
`magic_force_arm_value` (2989). Every failing check is reported (the checks are and-ed, not short-circuited) by
`AP_Arming::check_failed` as a CRITICAL STATUSTEXT tagged "Arm: " (the tag while `arm` runs them; "PreArm: " in the
1 Hz background run), and the COMMAND_ACK is FAILED. Armed with every check off, `arm` warns "Warning: Arming Checks
Disabled".

Which checks run (`AP_Arming::check_enabled`): on 4.5 ARMING_CHECK, a bitmask of checks to perform (bit 0 all, the
default 1); on 4.7 ARMING_SKIPCHK, a bitmask of checks to skip (default 0: every one runs; -1 skips them all), the
same bit for the same check (the parameter's rename and inversion is ArduPilot PR #31568). "Every check off" on 4.7 is
taken as every bit set (the 4.7 source was not at hand).

The built-in vehicle's IMU, compass and RC are always healthy; what it can fail is what its faults reach:
- the barometer (bit 1, `AP_Arming::barometer_checks`): a depth sensor not healthy, or not found at boot, fails
  `AP_Baro::arming_checks` with "not healthy": "Baro: not healthy";
- the battery (bit 8, `AP_Arming::battery_checks`, `AP_BattMonitor_Backend::arming_checks`): the first of "below
  minimum arming voltage" (BATT_ARM_VOLT), "below minimum arming capacity" (BATT_ARM_MAH), "low voltage failsafe",
  "low capacity failsafe", "critical voltage failsafe", "critical capacity failsafe" (BATT_LOW_/CRT_ VOLT and MAH
  against the reading now, 0 off): "Battery 1 <reason>".
Pure: the caller sends the texts and the ACK.
"""

from __future__ import annotations

ALL, BARO, BATTERY = 1 << 0, 1 << 1, 1 << 8
FORCE_ARM = 2989.0         # param2 of MAV_CMD_COMPONENT_ARM_DISARM that arms without the checks
CHECKS_OFF_WARNING = "Warning: Arming Checks Disabled"


def enabled(params, check: int) -> bool:
    """`AP_Arming::check_enabled` for this firmware's parameter."""
    if params.firmware == "4.5":
        performed = int(params["ARMING_CHECK"])
        return bool(performed & ALL or performed & check)
    return not int(params["ARMING_SKIPCHK"]) & check


def all_off(params) -> bool:
    """No check runs: `arm` warns CHECKS_OFF_WARNING after arming."""
    if params.firmware == "4.5":
        return int(params["ARMING_CHECK"]) == 0
    return int(params["ARMING_SKIPCHK"]) == -1


def failures(params, sensors) -> list[str]:
    """The texts (without their "Arm: " tag) of the enabled checks that fail now; empty: the vehicle may arm."""
    found = []
    if enabled(params, BARO) and not (sensors.depth_present and sensors.depth_healthy):
        found.append("Baro: not healthy")
    if enabled(params, BATTERY) and (reason := _battery(params, sensors)) is not None:
        found.append(f"Battery 1 {reason}")
    return found


def _battery(params, sensors) -> str | None:
    left = params["BATT_CAPACITY"] - sensors.consumed_mah
    volts = sensors.voltage

    def under(limit: float, value: float) -> bool:
        return limit > 0 and value < limit

    for failed, reason in ((under(params["BATT_ARM_VOLT"], volts), "below minimum arming voltage"),
                           (under(params["BATT_ARM_MAH"], left), "below minimum arming capacity"),
                           (under(params["BATT_LOW_VOLT"], volts), "low voltage failsafe"),
                           (under(params["BATT_LOW_MAH"], left), "low capacity failsafe"),
                           (under(params["BATT_CRT_VOLT"], volts), "critical voltage failsafe"),
                           (under(params["BATT_CRT_MAH"], left), "critical capacity failsafe")):
        if failed:
            return reason
    return None
