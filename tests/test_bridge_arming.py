"""The built-in vehicle's arming checks, over MAVLink (`sim_bridge.arming`): a failing check refuses the arming
with FAILED and a CRITICAL "Arm: ..." per failure, as `AP_Arming::arm` does; 4.7's ARMING_SKIPCHK skips a check by
its bit, 4.5's ARMING_CHECK performs the checks it names; param2 = 2989 arms without them."""

from __future__ import annotations

import pytest
from test_bridge_gcs import BridgeThread, Gcs, mavutil

from rov_mav.model.vehicle_faults import parse_vehicle_faults

mav = mavutil.mavlink
SPEEDUP = 10.0
QUIET = {"FS_PILOT_INPUT": 0, "FS_GCS_ENABLE": 0}
ARM = mav.MAV_CMD_COMPONENT_ARM_DISARM
BARO_FAILED = "Arm: Baro: not healthy"
VOLTAGE_LOW = "Arm: Battery 1 below minimum arming voltage"


def _arm(gcs: Gcs, force: bool = False) -> tuple[int, list[tuple[int, str]]]:
    """The COMMAND_ACK's result of one arming request and the STATUSTEXTs (severity, text) that came with it."""
    gcs.drop_queued()
    gcs.send("command_long", 1, 1, ARM, 0, 1.0, 2989.0 if force else 0.0, 0, 0, 0, 0, 0)
    ack = gcs.recv("COMMAND_ACK", cond=lambda m: m.command == ARM)
    texts = [(m.severity, m.text) for m in gcs.collect(0.3, ["STATUSTEXT"])]
    return ack.result, texts


def _armed(gcs: Gcs) -> bool:
    heartbeat = gcs.recv("HEARTBEAT", cond=lambda m: m.get_srcSystem() == 1)
    return bool(heartbeat.base_mode & mav.MAV_MODE_FLAG_SAFETY_ARMED)


@pytest.mark.parametrize("firmware", ["4.7", "4.5"])
def test_a_failed_depth_sensor_refuses_the_arming_until_its_check_is_skipped_or_the_arming_forced(firmware):
    faults = parse_vehicle_faults(["depth-sensor@0s"])
    with BridgeThread(SPEEDUP, params=QUIET, vehicle_faults=faults, firmware=firmware) as b:
        gcs = Gcs(b.port, SPEEDUP)
        try:
            gcs.connect()
            result, texts = _arm(gcs)
            assert result == mav.MAV_RESULT_FAILED and (mav.MAV_SEVERITY_CRITICAL, BARO_FAILED) in texts
            assert not _armed(gcs)
            result, _ = _arm(gcs, force=True)                # magic_force_arm_value
            assert result == mav.MAV_RESULT_ACCEPTED and _armed(gcs)
            gcs.command(ARM, 0.0)
            if firmware == "4.7":
                gcs.set_param("ARMING_SKIPCHK", 2, mav.MAV_PARAM_TYPE_INT32)      # bit 1: the barometer's
            else:
                gcs.set_param("ARMING_CHECK", 0x1FFFFC, mav.MAV_PARAM_TYPE_INT32)  # every check but "all" and baro
            result, texts = _arm(gcs)
            assert result == mav.MAV_RESULT_ACCEPTED and _armed(gcs), texts
            assert not any(text.startswith("Arm:") for _, text in texts)
        finally:
            gcs.close()


def test_every_failing_check_is_reported_and_checks_all_off_arm_with_a_warning():
    """4.5: a voltage under BATT_ARM_VOLT and a failed depth sensor both reported at one arming; ARMING_CHECK = 0
    arms, warning that the checks are off."""
    faults = parse_vehicle_faults(["depth-sensor@0s"])
    with BridgeThread(SPEEDUP, params={**QUIET, "BATT_ARM_VOLT": 20.0}, vehicle_faults=faults, firmware="4.5") as b:
        gcs = Gcs(b.port, SPEEDUP)
        try:
            gcs.connect()
            result, texts = _arm(gcs)
            assert result == mav.MAV_RESULT_FAILED
            assert {BARO_FAILED, VOLTAGE_LOW} <= {text for _, text in texts}
            gcs.set_param("ARMING_CHECK", 0, mav.MAV_PARAM_TYPE_INT32)
            result, texts = _arm(gcs)
            assert result == mav.MAV_RESULT_ACCEPTED and _armed(gcs)
            assert (mav.MAV_SEVERITY_WARNING, "Warning: Arming Checks Disabled") in texts
        finally:
            gcs.close()


def test_on_4_7_the_battery_check_is_skipped_by_its_own_bit_only():
    with BridgeThread(SPEEDUP, params={**QUIET, "BATT_ARM_VOLT": 20.0, "ARMING_SKIPCHK": 2}) as b:
        gcs = Gcs(b.port, SPEEDUP)
        try:
            gcs.connect()
            result, texts = _arm(gcs)                          # the barometer's bit skipped, not the battery's
            assert result == mav.MAV_RESULT_FAILED and VOLTAGE_LOW in {text for _, text in texts}
            gcs.set_param("ARMING_SKIPCHK", 2 | 256, mav.MAV_PARAM_TYPE_INT32)
            result, _ = _arm(gcs)
            assert result == mav.MAV_RESULT_ACCEPTED and _armed(gcs)
        finally:
            gcs.close()
