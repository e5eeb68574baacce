"""The bridge as a ground station sees it: pymavlink over real UDP/TCP sockets, against the bridge in-process (most
tests: quick to start) or as `rov-mav sim-bridge` in a subprocess (command-line flags, errors, signals; every
subprocess must also stop cleanly on SIGTERM).

Timing claims are checked on the vehicle's own clock (time_boot_ms), since it runs 10x faster than the wall."""

from __future__ import annotations

import signal
import socket
import subprocess
import time

import pytest
from bridge_helpers import (ROV_MAV, SPEEDUP, WAIT, BridgeProcess, BridgeThread, Gcs, free_port, mavutil, servo,
                            use_passthrough, wait_servo)

mav = mavutil.mavlink


@pytest.fixture
def bridge():
    with BridgeThread(speedup=SPEEDUP) as b:
        yield b


@pytest.fixture
def gcs(bridge):
    g = Gcs(bridge.port, speedup=SPEEDUP)
    g.connect()
    yield g
    g.close()


@pytest.mark.process
def test_heartbeat_is_ardusubs(gcs):
    gcs.override = [1500] * 8            # pilot input keeps the boot-time pilot failsafe away
    gcs.start_pump()
    hb = gcs.recv("HEARTBEAT", cond=lambda m: m.get_srcSystem() == 1 and m.system_status == mav.MAV_STATE_STANDBY)
    assert (hb.type, hb.autopilot, hb.base_mode, hb.custom_mode) == (12, 3, 81, 19)
    assert hb.get_srcComponent() == 1 and hb.get_msgbuf()[0] == 0xFD           # MAVLink 2
    msgs = gcs.collect(1.5, ["HEARTBEAT", "ATTITUDE"])
    times = [m.time_boot_ms / 1000 for m in msgs if m.get_type() == "ATTITUDE"]
    beats = sum(m.get_type() == "HEARTBEAT" for m in msgs)
    assert beats == pytest.approx(times[-1] - times[0], abs=1.5)                # 1 Hz of simulated time


@pytest.mark.process
def test_mode_changes_and_refusals(gcs):
    ack = gcs.command(mav.MAV_CMD_DO_SET_MODE, mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 2)
    assert ack.result == mav.MAV_RESULT_ACCEPTED
    assert gcs.recv("HEARTBEAT", cond=lambda m: m.custom_mode == 2).base_mode == 81
    gcs.send("set_mode", 1, mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 16)
    assert gcs.recv("COMMAND_ACK", cond=lambda m: m.command == 11).result == mav.MAV_RESULT_ACCEPTED
    assert gcs.recv("HEARTBEAT", cond=lambda m: m.custom_mode == 16).base_mode == 89
    for refused in (3, 42):                        # AUTO, which this vehicle does not fly, and no mode at all
        ack = gcs.command(mav.MAV_CMD_DO_SET_MODE, mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, refused)
        assert ack.result == mav.MAV_RESULT_FAILED
    assert gcs.command(mav.MAV_CMD_DO_SET_MODE, 0, 19).result == mav.MAV_RESULT_DENIED
    assert gcs.recv("HEARTBEAT").custom_mode == 16
    assert gcs.command(mav.MAV_CMD_DO_SET_MODE, 1, 19).result == mav.MAV_RESULT_ACCEPTED
    assert gcs.recv("HEARTBEAT", cond=lambda m: m.custom_mode == 19)


@pytest.mark.process
def test_arm_and_disarm_are_acknowledged(gcs):
    gcs.start_pump()
    assert gcs.command(mav.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == mav.MAV_RESULT_ACCEPTED
    assert gcs.recv("HEARTBEAT", cond=lambda m: m.base_mode & 128).base_mode == 81 + 128
    assert gcs.command(mav.MAV_CMD_COMPONENT_ARM_DISARM, 0).result == mav.MAV_RESULT_ACCEPTED
    assert gcs.recv("HEARTBEAT", cond=lambda m: not m.base_mode & 128).base_mode == 81
    assert gcs.command(mav.MAV_CMD_COMPONENT_ARM_DISARM, 7).result == mav.MAV_RESULT_UNSUPPORTED
    assert gcs.command(12345).result == mav.MAV_RESULT_UNSUPPORTED


@pytest.mark.process
def test_parameters_list_read_set(gcs):
    gcs.send("param_request_list", 1, 1)
    values = {}
    first = gcs.recv("PARAM_VALUE")
    values[first.param_id] = first
    while len(values) < first.param_count:
        m = gcs.recv("PARAM_VALUE", 5.0)
        values[m.param_id] = m
    assert sorted(m.param_index for m in values.values()) == list(range(first.param_count))
    expected = {"SERVO1_FUNCTION": 33, "SERVO8_FUNCTION": 40, "SERVO9_FUNCTION": 0, "RC_OVERRIDE_TIME": 3,
                "MAV_GCS_SYSID": 255, "MAV_SYSID": 1, "FS_GCS_ENABLE": 2, "FS_GCS_TIMEOUT": 5, "FS_PILOT_INPUT": 2,
                "FS_PILOT_TIMEOUT": 3, "MAV1_EXTRA1": 10, "MAV1_POSITION": 3, "SIM_SPEEDUP": SPEEDUP}
    assert {k: values[k].param_value for k in expected} == expected
    assert values["SERVO1_FUNCTION"].param_type == mav.MAV_PARAM_TYPE_INT16
    assert values["RC_OVERRIDE_TIME"].param_type == mav.MAV_PARAM_TYPE_REAL32
    # as ArduSub: integers rounded and saturated to their type, documented ranges not enforced
    assert gcs.set_param("SERVO3_FUNCTION", 52.6, mav.MAV_PARAM_TYPE_INT16).param_value == 52
    assert gcs.set_param("FS_GCS_ENABLE", 1000, mav.MAV_PARAM_TYPE_INT8).param_value == 127
    assert gcs.set_param("RC_OVERRIDE_TIME", 250.0).param_value == 250.0
    assert gcs.get_param("SERVO3_FUNCTION").param_value == 52
    gcs.send("param_set", 1, 1, b"NO_SUCH_PARAM", 1.0, mav.MAV_PARAM_TYPE_REAL32)
    gcs.send("param_request_read", 1, 1, b"NO_SUCH_PARAM", -1)
    assert not [m for m in gcs.collect(1.0, ["PARAM_VALUE"]) if m.param_id == "NO_SUCH_PARAM"]
    gcs.send("param_request_read", 1, 1, b"", values["FS_PILOT_TIMEOUT"].param_index)
    assert gcs.recv("PARAM_VALUE").param_id == "FS_PILOT_TIMEOUT"


@pytest.mark.process
def test_firmware_45_parameter_names():
    with BridgeThread(SPEEDUP, firmware="4.5") as b:
        g = Gcs(b.port, SPEEDUP)
        try:
            g.connect()
            assert g.get_param("SYSID_MYGCS").param_value == 255
            assert g.get_param("SR0_EXTRA1").param_value == 10
            g.send("param_request_read", 1, 1, b"MAV_GCS_SYSID", -1)
            assert not [m for m in g.collect(1.0, ["PARAM_VALUE"]) if m.param_id == "MAV_GCS_SYSID"]
        finally:
            g.close()


@pytest.mark.process
def test_overrides_from_another_sysid_are_ignored(bridge, gcs):
    use_passthrough(gcs)
    gcs.start_pump()
    intruder = Gcs(bridge.port, SPEEDUP, sysid=42)
    try:
        for _ in range(5):
            intruder.rc_override([1700] * 8)
            time.sleep(0.05)
        wait_servo(gcs, lambda s: s == [1500] * 8)
        assert all(servo(m) == [1500] * 8 for m in gcs.collect(0.5, ["SERVO_OUTPUT_RAW"]))
        gcs.rc_override([1600] * 8)
        wait_servo(gcs, lambda s: s == [1600] * 8)
    finally:
        intruder.close()


@pytest.mark.process
def test_passthrough_ignores_arming_and_holds_after_overrides_stop(gcs):
    assert gcs.set_param("FS_PILOT_INPUT", 0, mav.MAV_PARAM_TYPE_INT8).param_value == 0
    use_passthrough(gcs)
    gcs.override = [1600, 1600, 1400, 1400, 1550, 1550, 1450, 1450]
    gcs.start_pump()
    wait_servo(gcs, lambda s: s == gcs.override)          # disarmed, and yet driven
    gcs.override = None
    stopped = gcs.sim_time_now()
    msgs = gcs.collect(0.9, ["SERVO_OUTPUT_RAW"])         # 9 s simulated, three times RC_OVERRIDE_TIME
    assert msgs[-1].time_usec / 1e6 > stopped + 6.0
    assert all(servo(m) == [1600, 1600, 1400, 1400, 1550, 1550, 1450, 1450] for m in msgs)


@pytest.mark.process
def test_pilot_input_failsafe_disarms_neutralises_1_to_6_and_leaves_7_8_running(gcs):
    use_passthrough(gcs)
    gcs.override = [1600, 1600, 1500] + [1600] * 5       # the throttle at its trim: 4.7 arms only so
    gcs.start_pump()
    wait_servo(gcs, lambda s: s == gcs.override)
    assert gcs.command(mav.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == mav.MAV_RESULT_ACCEPTED
    gcs.recv("HEARTBEAT", cond=lambda m: m.base_mode & 128)
    gcs.override = None                                   # heartbeats go on, pilot input stops
    stopped = gcs.sim_time_now()
    gcs.recv("STATUSTEXT", cond=lambda m: m.text == "Lost manual control")
    fired = gcs.sim_time()
    assert 3.0 - 0.6 < fired - stopped < 3.0 + 1.5, (stopped, fired)
    hb = gcs.recv("HEARTBEAT")
    assert not hb.base_mode & 128 and hb.system_status == mav.MAV_STATE_CRITICAL
    m = wait_servo(gcs, lambda s: s[:6] == [1500] * 6)
    assert servo(m)[6:] == [1600, 1600]
    later = gcs.sim_time()
    assert servo(gcs.recv("SERVO_OUTPUT_RAW", cond=lambda m: m.time_usec / 1e6 > later + 5))[6:] == [1600, 1600]


@pytest.mark.process
def test_gcs_failsafe_disarms_after_its_timeout(gcs):
    assert gcs.set_param("FS_PILOT_INPUT", 0, mav.MAV_PARAM_TYPE_INT8).param_value == 0
    gcs.start_pump()
    assert gcs.command(mav.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == mav.MAV_RESULT_ACCEPTED
    gcs.recv("HEARTBEAT", cond=lambda m: m.base_mode & 128)
    gcs.heartbeats = False
    stopped = gcs.sim_time_now()
    hb = gcs.recv("HEARTBEAT", cond=lambda m: not m.base_mode & 128)
    fired = gcs.sim_time()
    assert 5.0 - 0.6 < fired - stopped < 5.3 + 1.5, (stopped, fired)    # 5 s timeout, 3.3 Hz check
    assert hb.system_status == mav.MAV_STATE_CRITICAL
    # announced once 30 s of uptime have passed (the warning's clock starts at boot), whenever the link was lost
    gcs.recv("STATUSTEXT", cond=lambda m: m.text == "MYGCS: 255, heartbeat lost", timeout=WAIT + 30 / SPEEDUP)


@pytest.mark.process
def test_overrides_alone_keep_the_gcs_failsafe_away(gcs):
    assert gcs.set_param("FS_PILOT_INPUT", 0, mav.MAV_PARAM_TYPE_INT8).param_value == 0
    gcs.override = [1500] * 8
    gcs.heartbeats = False
    gcs.heartbeat()
    gcs.start_pump()
    assert gcs.command(mav.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == mav.MAV_RESULT_ACCEPTED
    start = gcs.sim_time_now()
    gcs.recv("ATTITUDE", cond=lambda m: m.time_boot_ms / 1000 > start + 10)
    hb = gcs.recv("HEARTBEAT")
    assert hb.base_mode & 128 and hb.system_status == mav.MAV_STATE_ACTIVE


def rate(msgs, kind: str) -> float:
    """Messages of `kind` per simulated second."""
    times = [m.time_boot_ms / 1000 for m in msgs if m.get_type() == kind]
    return (len(times) - 1) / (times[-1] - times[0])


@pytest.mark.process
def test_default_rates_and_requested_intervals(gcs):
    gcs.start_pump()
    msgs = gcs.collect(1.5)
    assert rate(msgs, "ATTITUDE") == pytest.approx(10, rel=0.1)
    assert rate(msgs, "LOCAL_POSITION_NED") == pytest.approx(3, rel=0.15)
    assert rate(msgs, "GLOBAL_POSITION_INT") == pytest.approx(3, rel=0.15)
    assert not [m for m in msgs if m.get_type() == "ATTITUDE_QUATERNION"]
    assert gcs.set_interval(mav.MAVLINK_MSG_ID_ATTITUDE, 50).result == mav.MAV_RESULT_ACCEPTED
    assert gcs.set_interval(mav.MAVLINK_MSG_ID_LOCAL_POSITION_NED, 50).result == mav.MAV_RESULT_ACCEPTED
    assert gcs.set_interval(mav.MAVLINK_MSG_ID_ATTITUDE_QUATERNION, 20).result == mav.MAV_RESULT_ACCEPTED
    assert gcs.command(mav.MAV_CMD_SET_MESSAGE_INTERVAL, mav.MAVLINK_MSG_ID_VFR_HUD, -1).result == 0
    gcs.collect(0.2)
    msgs = gcs.collect(1.5)
    assert rate(msgs, "ATTITUDE") == pytest.approx(50, rel=0.05)
    assert rate(msgs, "LOCAL_POSITION_NED") == pytest.approx(50, rel=0.05)
    assert rate(msgs, "ATTITUDE_QUATERNION") == pytest.approx(20, rel=0.05)
    assert not [m for m in msgs if m.get_type() == "VFR_HUD"]
    ack = gcs.command(mav.MAV_CMD_SET_MESSAGE_INTERVAL, 9999, 1000)
    assert ack.result == mav.MAV_RESULT_DENIED
    interval, ack = gcs.get_interval(mav.MAVLINK_MSG_ID_ATTITUDE)
    assert (interval.interval_us, ack.result) == (20000, mav.MAV_RESULT_ACCEPTED)


@pytest.mark.process
def test_requested_messages(gcs):
    ack = gcs.command(mav.MAV_CMD_REQUEST_MESSAGE, mav.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
    assert ack.result == mav.MAV_RESULT_ACCEPTED
    version = gcs.recv("AUTOPILOT_VERSION")
    assert version.flight_sw_version == 0x040702FF                # 4.7.2, official (`send_autopilot_version`)
    assert gcs.command(mav.MAV_CMD_DO_SEND_BANNER).result == mav.MAV_RESULT_ACCEPTED
    assert gcs.recv("STATUSTEXT", cond=lambda m: m.text.startswith("ArduSub")).text == "ArduSub V4.7.2 (00000000)"
    assert version.capabilities & mav.MAV_PROTOCOL_CAPABILITY_MAVLINK2
    assert gcs.command(mav.MAV_CMD_REQUEST_MESSAGE, mav.MAVLINK_MSG_ID_HOME_POSITION).result == 0
    assert gcs.recv("HOME_POSITION").latitude == round(-35.363261e7)
    assert gcs.command(mav.MAV_CMD_REQUEST_MESSAGE, mav.MAVLINK_MSG_ID_ATTITUDE_QUATERNION).result == 0
    q = gcs.recv("ATTITUDE_QUATERNION")
    assert (q.q1, q.q2, q.q3, q.q4) == pytest.approx((1, 0, 0, 0), abs=1e-6)
    # ArduPilot's GCS_MAVLINK::handle_command_request_message: an id it cannot send is FAILED
    assert gcs.command(mav.MAV_CMD_REQUEST_MESSAGE, 9999).result == mav.MAV_RESULT_FAILED


@pytest.mark.process
def test_telemetry_contents_at_rest():
    with BridgeThread(SPEEDUP, start_depth=2.0, origin=(47.5, -122.25, 10.0)) as b:
        g = Gcs(b.port, SPEEDUP)
        try:
            g.connect()
            p = g.recv("SCALED_PRESSURE2")
            assert p.press_diff == pytest.approx(1000 * 9.81 * 2 / 100, rel=1e-3)
            assert p.press_abs == pytest.approx(1013.25 + 196.2, rel=1e-3)
            pos = g.recv("GLOBAL_POSITION_INT")
            assert (pos.lat, pos.lon, pos.alt, pos.relative_alt) == (475000000, -1222500000, 8000, -2000)
            local = g.recv("LOCAL_POSITION_NED")
            assert (local.x, local.y, local.z) == pytest.approx((0, 0, 2), abs=1e-3)
            hud = g.recv("VFR_HUD")
            assert hud.alt == pytest.approx(-2, abs=1e-3) and hud.heading == 0
            status = g.recv("SYS_STATUS")
            assert status.voltage_battery == pytest.approx(16785, abs=30) and status.battery_remaining == 100
            battery = g.recv("BATTERY_STATUS")
            assert battery.voltages[0] == status.voltage_battery and battery.battery_remaining == 100
            rc = g.recv("RC_CHANNELS")
            assert [rc.chan1_raw, rc.chan8_raw, rc.chan9_raw] == [1500, 1500, 0]   # 4.7 (4.5.3: 1100 on 9)
            clock = g.recv("SYSTEM_TIME")
            assert abs(clock.time_unix_usec / 1e6 - time.time()) < 3600
            assert clock.time_boot_ms > 0
        finally:
            g.close()


@pytest.mark.process
def test_several_links_at_once_udpout_udpin_tcpin(tmp_path):
    watch_port, tcp_port = free_port(), free_port(socket.SOCK_STREAM)
    watch = mavutil.mavlink_connection(f"udpin:127.0.0.1:{watch_port}")       # a ground station on its port
    args = ("--out", f"udpout:127.0.0.1:{watch_port}", "--listen", f"tcpin:127.0.0.1:{tcp_port}",
            "--param", "FS_GCS_TIMEOUT=6")
    with BridgeProcess(tmp_path, *args) as b:
        udp = Gcs(b.port, SPEEDUP)
        tcp = None
        try:
            udp.connect()
            deadline = time.monotonic() + WAIT
            while tcp is None:
                try:
                    tcp = mavutil.mavlink_connection(f"tcp:127.0.0.1:{tcp_port}", source_system=250,
                                                     autoreconnect=False)
                except OSError:
                    assert time.monotonic() < deadline
                    time.sleep(0.2)
            assert tcp.recv_match(type="HEARTBEAT", blocking=True, timeout=WAIT) is not None
            assert watch.recv_match(type="HEARTBEAT", blocking=True, timeout=WAIT) is not None
            tcp.mav.command_long_send(1, 1, mav.MAV_CMD_DO_SET_MODE, 0, 1, 2, 0, 0, 0, 0, 0)
            ack = tcp.recv_match(type="COMMAND_ACK", blocking=True, timeout=WAIT)
            assert ack.result == mav.MAV_RESULT_ACCEPTED
            assert watch.recv_match(type="HEARTBEAT", blocking=True, timeout=WAIT,
                                    condition="HEARTBEAT.custom_mode == 2") is not None
            assert udp.get_param("FS_GCS_TIMEOUT").param_value == 6.0
            udp.set_param("FS_GCS_TIMEOUT", 7.0)        # a PARAM_SET is echoed on every link
            for conn in (tcp, watch):
                m = conn.recv_match(type="PARAM_VALUE", blocking=True, timeout=WAIT)
                assert (m.param_id, m.param_value) == ("FS_GCS_TIMEOUT", 7.0)
        finally:
            udp.close()
            watch.close()
            if tcp is not None:
                tcp.close()


@pytest.mark.process
def test_port_in_use_and_bad_address_are_one_line_errors():
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as taken:
        taken.bind(("127.0.0.1", 0))
        port = taken.getsockname()[1]
        r = subprocess.run([ROV_MAV, "sim-bridge", "--listen", f"udpin:127.0.0.1:{port}"], capture_output=True,
                           text=True, timeout=60)
    assert r.returncode == 1 and r.stderr.strip().count("\n") == 0
    assert r.stderr.strip() == f"rov-mav sim-bridge: error: udpin:127.0.0.1:{port}: address already in use"



def test_bad_addresses_are_one_line_errors(capsys):
    from rov_mav.cli import main
    assert main(["sim-bridge", "--out", "udpout:no-such-host.invalid:14550"]) == 1
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and err.startswith("rov-mav sim-bridge: error: udpout:no-such-host.invalid:14550: bad")
    with pytest.raises(SystemExit) as exc:
        main(["sim-bridge", "--listen", "udpin:127.0.0.1:99999"])
    assert exc.value.code == 2 and "port must be a number from 1 to 65535" in capsys.readouterr().err
    assert main(["sim-bridge", "--param", "NO_SUCH_PARAM=1"]) == 2
    assert capsys.readouterr().err.strip() == "rov-mav sim-bridge: error: unknown parameter NO_SUCH_PARAM"


@pytest.mark.process
def test_stops_cleanly_on_ctrl_c(tmp_path):
    with BridgeProcess(tmp_path) as b:             # (and on SIGTERM: every BridgeProcess ends with one)
        g = Gcs(b.port, SPEEDUP)
        g.connect()
        g.close()
        b.proc.send_signal(signal.SIGINT)
        assert b.proc.wait(WAIT) == 0
    assert "sim-bridge: stopped at t=" in b.output and "Traceback" not in b.output


@pytest.mark.process
def test_help_explains_every_option():
    r = subprocess.run([ROV_MAV, "sim-bridge", "--help"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0
    for flag in ("--out", "--listen", "--speedup", "--environment", "--firmware", "--origin", "--start-depth",
                 "--step", "--seed", "--param", "--vehicle", "udpout:127.0.0.1:14550", "SIGTERM", "passthrough"):
        assert flag in r.stdout
