"""ArduSub's assisted modes on the bridge's vehicle (logic, mixer, T200, plant; no sockets but in the last test):
STABILIZE keeps it level, ALT_HOLD its depth, POSHOLD its place and every assisted mode its heading, against
constant disturbances that move it away in MANUAL; ACRO turns the sticks into body rates."""

from __future__ import annotations

import math

import numpy as np
import pytest
from bridge_helpers import BridgeThread, Gcs, mavutil

from rov_mav.model.environment import Environment
from rov_mav.model.plant import Plant
from rov_mav.model.thrusters import load_t200
from rov_mav.model.vehicle import load_vehicle
from sim_bridge.autopilot.ardusub import MODES, ArduSub
from sim_bridge.hardware.battery import Battery
from sim_bridge.autopilot.params import Params
from sim_bridge.hardware.physics import Physics

STEP = 0.0025
mav = mavutil.mavlink


def fly(mode: str, channels: list[int], seconds: float, disturbance=(0, 0, 0, 0, 0, 0), depth: float = 5.0):
    """Armed in `mode` with RC channels 1-8 held at `channels` for `seconds`; the true (eta, nu) at the end."""
    vehicle = load_vehicle()
    plant = Plant(vehicle, Environment(disturbance=np.array(disturbance, dtype=float)),
                  eta0=np.array([0, 0, depth, 0, 0, 0.0]))
    physics = Physics(vehicle, plant, Battery(), load_t200(), STEP)
    params = Params()
    params.set("FS_PILOT_INPUT", 0)
    params.set("FS_GCS_ENABLE", 0)
    sub = ArduSub(params)
    assert sub.set_mode(MODES[mode])
    sub.rc_override(255, channels + [0] * 10, 0.0)
    sub.arm(True)
    for k in range(int(seconds / STEP)):
        sub.update(k * STEP, (plant.eta, plant.nu))
        physics.step(sub.servo_outputs()[:8])
    return plant.eta, plant.nu


NEUTRAL = [1500] * 8


def test_stabilize_keeps_level_where_manual_pitches_over():
    forward = [1500, 1500, 1500, 1500, 1560, 1500, 1500, 1500]
    eta, nu = fly("MANUAL", forward, 10.0)
    assert eta[4] > math.radians(20)
    eta, nu = fly("STABILIZE", forward, 10.0)
    assert abs(eta[4]) < math.radians(3) and abs(eta[3]) < math.radians(1) and nu[0] > 0.1


def test_alt_hold_holds_depth_against_a_downward_push():
    eta, _ = fly("MANUAL", NEUTRAL, 10.0, disturbance=(0, 0, 8, 0, 0, 0))
    assert eta[2] > 5.0 + 1.0
    eta, nu = fly("ALT_HOLD", NEUTRAL, 20.0, disturbance=(0, 0, 8, 0, 0, 0))
    assert eta[2] == pytest.approx(5.0, abs=0.02) and abs(nu[2]) < 0.01


def test_alt_hold_throttle_stick_changes_depth():
    eta, _ = fly("ALT_HOLD", [1500, 1500, 1700, 1500, 1500, 1500, 1500, 1500], 10.0)
    assert eta[2] < 5.0 - 1.0                                    # stick up: it rises


def test_poshold_holds_position_and_heading_against_a_sideways_push_and_a_twist():
    push = (3, 4, 0, 0, 0, 0.3)
    eta, nu = fly("MANUAL", NEUTRAL, 10.0, disturbance=push)
    assert math.hypot(eta[0], eta[1]) > 0.5 and nu[5] > 0.4          # drifts while it spins
    eta, nu = fly("POSHOLD", NEUTRAL, 25.0, disturbance=push)
    assert math.hypot(eta[0], eta[1]) < 0.05 and abs(eta[5]) < math.radians(3)
    assert eta[2] == pytest.approx(5.0, abs=0.02)


def test_acro_yaw_stick_commands_a_yaw_rate():
    _, nu = fly("ACRO", [1500, 1500, 1500, 1700, 1500, 1500, 1500, 1500], 3.0)
    assert nu[5] == pytest.approx(0.5 * math.radians(90), rel=0.2)    # P only: the dead band costs some rate


@pytest.mark.process
def test_alt_hold_over_mavlink_holds_depth_against_a_push():
    with BridgeThread(10.0, start_depth=3.0, environment=Environment(disturbance=np.array([0, 0, 8.0, 0, 0, 0]))) \
            as running:
        gcs = Gcs(running.port, 10.0, rate=5.0)
        try:
            gcs.connect()
            gcs.override = [1500] * 8
            gcs.start_pump()
            assert gcs.command(mav.MAV_CMD_DO_SET_MODE, 1, MODES["ALT_HOLD"]).result == mav.MAV_RESULT_ACCEPTED
            assert gcs.command(mav.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == mav.MAV_RESULT_ACCEPTED
            gcs.sim_time_now()
            engaged = gcs.recv("LOCAL_POSITION_NED")              # the depth where the hold began (it was sinking)
            m = gcs.recv("LOCAL_POSITION_NED", cond=lambda m: m.time_boot_ms > engaged.time_boot_ms + 30000)
            assert m.z == pytest.approx(engaged.z, abs=0.05) and abs(m.vz) < 0.02
            servo = gcs.recv("SERVO_OUTPUT_RAW")
            assert all(getattr(servo, f"servo{i}_raw") < 1500 for i in range(5, 9))   # pushing up
        finally:
            gcs.close()
