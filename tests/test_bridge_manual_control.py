"""MANUAL_CONTROL, the pilot's joystick, as ArduSub 4.7 handles it (4.5.3's channels 9-11 noted where they differ):
pymavlink stations over real UDP against the
bridge in-process, timed on the vehicle's clock. The hazard: with passthrough outputs (SERVOn_FUNCTION 51..58) a
station whose joystick is at rest overwrites a controller's eight thruster commands with 1500."""

from __future__ import annotations

import time

import pytest
from bridge_helpers import BridgeThread, Gcs, mavutil
from bridge_helpers import SPEEDUP, use_passthrough, wait_servo

pytestmark = pytest.mark.process      # starts a process or the bridge (tests/conftest.py)

mav = mavutil.mavlink
NEUTRAL = (0, 0, 500, 0)


@pytest.fixture
def bridge():
    with BridgeThread(speedup=SPEEDUP) as b:
        yield b


@pytest.fixture
def gcs(bridge):
    g = Gcs(bridge.port, speedup=SPEEDUP, rate=25.0)
    g.connect()
    yield g
    g.close()


def rc(m) -> list[int]:
    return [getattr(m, f"chan{i}_raw") for i in range(1, 12)]


def test_a_neutral_joystick_overrides_passthrough_outputs(bridge, gcs):
    use_passthrough(gcs)
    gcs.override = [1600, 1400, 1650, 1350, 1700, 1300, 1550, 1450]      # a controller driving the thrusters
    gcs.start_pump()
    wait_servo(gcs, lambda s: s == gcs.override)
    pilot = Gcs(bridge.port, SPEEDUP)                                    # the pilot's station, also sysid 255
    try:
        gcs.override = None
        for _ in range(5):
            pilot.manual_control(*NEUTRAL)
            time.sleep(0.02)
        wait_servo(gcs, lambda s: s == [1500] * 8)
        m = gcs.recv("RC_CHANNELS")
        assert rc(m) == [1500] * 8 + [0] * 3             # 4.7: channels 9-11 never written (4.5.3: 1100)
    finally:
        pilot.close()


def test_a_deflected_stick_gives_ardusubs_pwm(gcs):
    gcs.joystick = (400, -200, 700, 100)
    gcs.start_pump()
    m = gcs.recv("RC_CHANNELS", cond=lambda m: m.chan5_raw != 1500)
    assert rc(m)[:8] == [1500, 1500, 1580, 1520, 1580, 1460, 1500, 1500]   # as ArduSub 4.5.3 SITL (1-8 unchanged)
    gcs.joystick = (-1000, 1000, 0, 1000)
    m = gcs.recv("RC_CHANNELS", cond=lambda m: m.chan5_raw == 1300)
    assert rc(m)[:6] == [1500, 1500, 1300, 1700, 1300, 1700]


@pytest.mark.parametrize("sysid, target", [(254, 1), (255, 0), (255, 2)])
def test_other_stations_and_other_targets_are_ignored(bridge, gcs, sysid, target):
    gcs.start_pump()
    other = Gcs(bridge.port, SPEEDUP, sysid=sysid)
    try:
        for _ in range(10):
            other.manual_control(400, 0, 900, 0, target=target)
            time.sleep(0.02)
        start = gcs.sim_time_now()
        msgs = [m for m in gcs.collect(0.5, ["RC_CHANNELS"]) if m.time_boot_ms / 1000 > start]
        assert msgs and all(rc(m)[:8] == [1500] * 8 for m in msgs)
    finally:
        other.close()


def test_the_joystick_feeds_the_pilot_input_and_gcs_failsafes(gcs):
    use_passthrough(gcs)
    gcs.heartbeats = False                  # MANUAL_CONTROL alone, as the only sign of the station
    gcs.heartbeat()
    gcs.joystick = (200, 0, 500, 0)
    gcs.start_pump()
    wait_servo(gcs, lambda s: s[4] == 1540)
    assert gcs.command(mav.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == mav.MAV_RESULT_ACCEPTED
    start = gcs.sim_time_now()
    gcs.recv("ATTITUDE", cond=lambda m: m.time_boot_ms / 1000 > start + 8)    # > FS_PILOT_TIMEOUT, FS_GCS_TIMEOUT
    hb = gcs.recv("HEARTBEAT")
    assert hb.base_mode & 128 and hb.system_status == mav.MAV_STATE_ACTIVE
    gcs.joystick = None
    stopped = gcs.sim_time_now()
    gcs.recv("STATUSTEXT", cond=lambda m: m.text == "Lost manual control")
    assert 3.0 - 0.6 < gcs.sim_time() - stopped < 3.0 + 1.5
    assert not gcs.recv("HEARTBEAT").base_mode & 128
    wait_servo(gcs, lambda s: s[:6] == [1500] * 6)
