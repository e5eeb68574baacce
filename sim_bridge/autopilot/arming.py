"""ArduSub's arming checks on the built-in vehicle.

`GCS_MAVLINK::handle_command_component_arm_disarm` (libraries/GCS_MAVLink/GCS_Common.cpp) arms through
`AP_Arming::arm` (libraries/AP_Arming/AP_Arming.cpp), which runs the pre-arm and arm checks unless param2 is
`magic_force_arm_value` (2989). Every failing check is reported (the checks are and-ed, not short-circuited) by
`AP_Arming::check_failed` as a CRITICAL STATUSTEXT tagged "Arm: " (the tag while `arm` runs them; "PreArm: " in the
1 Hz background run), and the COMMAND_ACK is FAILED. Armed with every check off, `arm` warns "Warning: Arming Checks
Disabled".

Which checks run (`AP_Arming::check_enabled`): on 4.5 ARMING_CHECK, a bitmask of checks to perform (bit 0 all); on
4.7 ARMING_SKIPCHK, a bitmask of checks to skip (-1 skips them all), the same bit for the same check (the rename and
inversion is ArduPilot PR #31568). Sub's defaults run only the RC, voltage and battery checks (ArduSub/Parameters.h's
defaults table: ARMING_CHECK = RC | VOLTAGE | BATTERY on 4.5, ARMING_SKIPCHK = ~(RC | VOLTAGE | BATTERY) on 4.7), so a
BlueROV2 with its defaults arms with a depth sensor that is not healthy.

Before any of them, 4.7's `AP_Arming_Sub::arm` refuses unless the throttle channel (RC3) is within RC3_TRIM +- RC3_DZ
("PreArm: Throttle not centered/close to trim", CRITICAL: it runs before `AP_Arming::arm` sets the "Arm: " tag) when
the RC check runs, RC_OPTIONS has bit 5 (ARMING_CHECK_THROTTLE, its default) and THR_ARM_POS is 1 (its default) - a
forced arm included. In passthrough, channel 3 carries a thruster's PWM.

`AP_Arming_Sub::pre_arm_checks` also refuses (unless forced, whatever the bits) a vehicle whose joystick buttons
cannot disarm it (`sim_bridge.autopilot.buttons.has_disarm_function`): "Must assign a disarm or arm_toggle button or
disarm
aux function" (the aux switches of an RC receiver are not emulated).

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

from sim_bridge.autopilot.buttons import has_disarm_function

ALL, BARO, RC, VOLTAGE, BATTERY = 1 << 0, 1 << 1, 1 << 6, 1 << 7, 1 << 8
SUB_CHECKS = RC | VOLTAGE | BATTERY      # the checks Sub's defaults run
RC_OPTION_ARMING_CHECK_THROTTLE = 1 << 5
THROTTLE_NOT_CENTERED = "PreArm: Throttle not centered/close to trim"
NO_DISARM_BUTTON = "Must assign a disarm or arm_toggle button or disarm aux function"
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


def throttle_refusal(params, throttle_in: int) -> str | None:
    """4.7's `AP_Arming_Sub::arm` before the checks (forced or not): the refusal when RC3 is off its trim by more than
    RC3_DZ, else None. 4.5.3 has no such check (its THR_ARM_POS came with 4.7's RC-receiver support, PR #29742)."""
    if params.firmware == "4.5" or not enabled(params, RC):
        return None
    if not int(params["RC_OPTIONS"]) & RC_OPTION_ARMING_CHECK_THROTTLE or int(params["THR_ARM_POS"]) != 1:
        return None
    if abs(throttle_in - params["RC3_TRIM"]) <= params["RC3_DZ"]:
        return None
    return THROTTLE_NOT_CENTERED


def failures(params, sensors) -> list[str]:
    """The texts (without their "Arm: " tag) of the enabled checks that fail now; empty: the vehicle may arm. First
    `AP_Arming_Sub::pre_arm_checks`' own, whatever the bits: a button must be able to disarm."""
    found = [] if has_disarm_function(params) else [NO_DISARM_BUTTON]
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
