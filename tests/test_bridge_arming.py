"""The built-in vehicle's arming checks, over MAVLink (`sim_bridge.autopilot.arming`): a failing check refuses the
arming
with FAILED and a CRITICAL "Arm: ..." per failure, as `AP_Arming::arm` does; 4.7's ARMING_SKIPCHK skips a check by
its bit, 4.5's ARMING_CHECK performs the checks it names, Sub's defaults the RC, voltage and battery checks only;
param2 = 2989 arms without them, but not past 4.7's throttle-centred check."""

from __future__ import annotations

import pytest
from bridge_helpers import BridgeThread, Gcs, mavutil

from rov_mav.model.vehicle_faults import parse_vehicle_faults

pytestmark = pytest.mark.process      # starts a process or the bridge (tests/conftest.py)

mav = mavutil.mavlink
SPEEDUP = 10.0
QUIET = {"FS_PILOT_INPUT": 0, "FS_GCS_ENABLE": 0}
ARM = mav.MAV_CMD_COMPONENT_ARM_DISARM
BARO_FAILED = "Arm: Baro: not healthy"
VOLTAGE_LOW = "Arm: Battery 1 below minimum arming voltage"
THROTTLE = "PreArm: Throttle not centered/close to trim"


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
def test_with_subs_defaults_a_failed_depth_sensor_arms_with_the_baro_check_on_it_refuses_unless_forced(firmware):
    """Sub's defaults run the RC, voltage and battery checks only (ArduSub/Parameters.h): a BlueROV2 arms with its
    depth sensor gone. With the barometer's check on, the arming is refused; forced, it arms."""
    faults = parse_vehicle_faults(["depth-sensor@0s"])
    with BridgeThread(SPEEDUP, params=QUIET, vehicle_faults=faults, firmware=firmware) as b:
        gcs = Gcs(b.port, SPEEDUP)
        try:
            gcs.connect()
            result, texts = _arm(gcs)
            assert result == mav.MAV_RESULT_ACCEPTED and _armed(gcs), texts
            assert not any(text.startswith("Arm:") for _, text in texts)
            gcs.command(ARM, 0.0)
            if firmware == "4.7":
                assert gcs.get_param("ARMING_SKIPCHK").param_value == ~(64 | 128 | 256)
                gcs.set_param("ARMING_SKIPCHK", ~(2 | 64 | 128 | 256), mav.MAV_PARAM_TYPE_INT32)  # baro on too
            else:
                assert gcs.get_param("ARMING_CHECK").param_value == 64 | 128 | 256
                gcs.set_param("ARMING_CHECK", 2 | 64 | 128 | 256, mav.MAV_PARAM_TYPE_INT32)
            result, texts = _arm(gcs)
            assert result == mav.MAV_RESULT_FAILED and (mav.MAV_SEVERITY_CRITICAL, BARO_FAILED) in texts
            assert not _armed(gcs)
            result, _ = _arm(gcs, force=True)                # magic_force_arm_value
            assert result == mav.MAV_RESULT_ACCEPTED and _armed(gcs)
        finally:
            gcs.close()


def test_every_failing_check_is_reported_and_checks_all_off_arm_with_a_warning():
    """4.5, ARMING_CHECK 1 (all): a voltage under BATT_ARM_VOLT and a failed depth sensor both reported at one
    arming; ARMING_CHECK = 0 arms, warning that the checks are off."""
    faults = parse_vehicle_faults(["depth-sensor@0s"])
    with BridgeThread(SPEEDUP, params={**QUIET, "BATT_ARM_VOLT": 20.0, "ARMING_CHECK": 1}, vehicle_faults=faults,
                      firmware="4.5") as b:
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


def test_on_4_7_the_battery_check_runs_by_default_and_is_skipped_by_its_own_bit():
    with BridgeThread(SPEEDUP, params={**QUIET, "BATT_ARM_VOLT": 20.0}) as b:
        gcs = Gcs(b.port, SPEEDUP)
        try:
            gcs.connect()
            result, texts = _arm(gcs)
            assert result == mav.MAV_RESULT_FAILED and VOLTAGE_LOW in {text for _, text in texts}
            gcs.set_param("ARMING_SKIPCHK", ~(64 | 128), mav.MAV_PARAM_TYPE_INT32)      # the battery's bit skipped
            result, _ = _arm(gcs)
            assert result == mav.MAV_RESULT_ACCEPTED and _armed(gcs)
        finally:
            gcs.close()


def _throttle(gcs: Gcs, pwm: int) -> None:
    """Override channel 3 (the throttle) with `pwm` from the GCS sysid until RC_CHANNELS shows it."""
    gcs.send("rc_channels_override", 1, 1, 1500, 1500, pwm, 1500, 1500, 1500, 1500, 1500, *([0] * 10))
    gcs.recv("RC_CHANNELS", cond=lambda m: m.chan3_raw == pwm)


@pytest.mark.parametrize("firmware", ["4.7", "4.5"])
def test_4_7_arms_only_with_the_throttle_channel_at_its_trim_even_forced(firmware):
    """AP_Arming_Sub::arm (4.7): RC3 beyond RC3_TRIM +- RC3_DZ refuses before the checks, a forced arm too; a wider
    dead zone or the RC check skipped lets it arm. 4.5.3 has no such check."""
    with BridgeThread(SPEEDUP, params=QUIET, firmware=firmware) as b:
        gcs = Gcs(b.port, SPEEDUP)
        try:
            gcs.connect()
            _throttle(gcs, 1700)
            result, texts = _arm(gcs)
            if firmware == "4.5":
                assert result == mav.MAV_RESULT_ACCEPTED and _armed(gcs)
                return
            assert result == mav.MAV_RESULT_FAILED and texts == [(mav.MAV_SEVERITY_CRITICAL, THROTTLE)]
            result, texts = _arm(gcs, force=True)
            assert result == mav.MAV_RESULT_FAILED and texts == [(mav.MAV_SEVERITY_CRITICAL, THROTTLE)]
            assert not _armed(gcs)
            gcs.set_param("RC3_DZ", 200, mav.MAV_PARAM_TYPE_INT16)
            _throttle(gcs, 1700)
            assert _arm(gcs)[0] == mav.MAV_RESULT_ACCEPTED and _armed(gcs)
            gcs.command(ARM, 0.0)
            gcs.set_param("RC3_DZ", 0, mav.MAV_PARAM_TYPE_INT16)
            gcs.set_param("ARMING_SKIPCHK", -1, mav.MAV_PARAM_TYPE_INT32)             # the RC check skipped
            _throttle(gcs, 1700)
            assert _arm(gcs)[0] == mav.MAV_RESULT_ACCEPTED and _armed(gcs)
        finally:
            gcs.close()
