"""`rov-mav run --output motor-test`: the law's PWMs as ArduSub's motor test (MAV_CMD_DO_MOTOR_TEST) with the outputs
left on their motors. The point of it is what happens when the runner dies without a word: ArduSub ends the test
and disarms 0.5 s after the last command, where RCIN passthrough (`--output thrusters`) keeps the last PWM on the
channels its failsafes do not reset. Both are shown here against a bridge process, the runner killed with SIGKILL.

The bridge runs at 3x (not the suite's 10x): the motor test's 0.5 s is then 0.17 s of wall time, which a loaded
machine's scheduler does not take from the runner's loop."""

from __future__ import annotations

import json
import signal
import time

import pytest
from pymavlink import mavutil
from run_helpers import (
    WAIT,
    armed,
    assert_left_safe,
    bridge_with_checker,
    checker,
    fresh,
    servo_functions,
    runner_against,
    servo_outputs,
    short_mission,
)

from rov_mav import cli
from rov_mav.flight.session.link import mavlink
from rov_mav.mission.missions import load_mission
from rov_mav.review.dive import DiveRecorder
from rov_mav.review.dive_review import review_dive

SPEEDUP = 3.0
MOTORS = list(range(33, 41))         # SERVOn_FUNCTION of motors 1..8
PASSTHROUGH = list(range(51, 59))    # ... of RCIN1..8


def _flying(gcs, functions: list[int]) -> None:
    """The run's outputs are off neutral on the given routing."""
    deadline = time.monotonic() + WAIT
    while servo_outputs(gcs) == [1500] * 8:
        assert time.monotonic() < deadline, "the outputs never left neutral"
    assert servo_functions(gcs) == functions


@pytest.mark.process
def test_motor_test_flies_missions_back_to_back_and_leaves_the_vehicle_as_found(tmp_path):
    """A mission flown on the motors' own routing (no parameter changed), then a second right after it: ArduSub ends
    every test by its timeout (a disarm does not end it) and refuses a new one for 10 s after, so the second run
    holds neutral until the vehicle accepts, then flies and completes. The first run's MAVLink log, reviewed as any
    telemetry log: its thruster commands are the DO_MOTOR_TEST stream, at the run's rate and latency."""
    metrics, log = tmp_path / "metrics.json", tmp_path / "log"
    first = short_mission(tmp_path, goto_x=2.0, hold=2.0)
    bridge, checker_port = bridge_with_checker(tmp_path, "--start-depth", "1", speedup=SPEEDUP)
    with bridge:
        gcs = checker(checker_port, speedup=SPEEDUP)
        try:
            with runner_against(bridge, first, "--output", "motor-test", "--metrics", str(metrics), "--log", str(log)) as run:
                run.wait_for("the thrusters through ArduSub's motor test")
                _flying(gcs, MOTORS)
                assert run.wait() == 0, run.output
            assert_left_safe(gcs)
            with runner_against(bridge, short_mission(tmp_path, goto_x=0.4, hold=1.0), "--output", "motor-test") as rerun:
                assert rerun.wait() == 0, rerun.output
            assert_left_safe(gcs)
            assert fresh(gcs, "HEARTBEAT").custom_mode == 19
        finally:
            gcs.close()
    result = json.loads(metrics.read_text())
    assert result["completed"] and result["rms_position_error_m"] < 0.10, result
    review = review_dive(log / "mavlink.tlog", load_mission(first)).metrics
    loop = review["loop"]
    assert loop["source"].startswith("MAV_CMD_DO_MOTOR_TEST from sysid")
    # Every tick's eight commands are there, and more: the held PWMs resent when a tick comes late (a loaded
    # machine) and the stop's neutral. So the first command after a state is the tick's or an earlier resend.
    assert loop["ticks"] >= result["loop"]["ticks"]
    assert loop["latency_p50_ms"] <= result["loop"]["latency_p50_ms"] + 0.5
    assert review["saturation"]["commands"]["samples"] == loop["ticks"]
    assert "SERVO1..8_FUNCTION set" not in run.output and "restored SERVO" not in run.output
    assert "disarmed (confirmed by HEARTBEAT)" in run.output and "motor test no longer sent" in run.output


@pytest.mark.process
@pytest.mark.parametrize("output", ["motor-test", "thrusters"])
def test_a_run_killed_outright(tmp_path, output):
    """SIGKILL mid-mission, nothing said to the vehicle. motor-test: ArduSub ends the test ("Motor test timed
    out!"), disarms and every output reads 1500, within a second of vehicle time. thrusters: the hazard it avoids -
    6 s of vehicle time later (past RC_OVERRIDE_TIME and the pilot-input failsafe) outputs 7 and 8, on RCIN
    passthrough, still hold the dead run's last PWM."""
    mission = short_mission(tmp_path, goto_x=6.0)
    bridge, checker_port = bridge_with_checker(tmp_path, "--start-depth", "1", speedup=SPEEDUP)
    with runner_against(bridge, mission, "--output", output) as run, bridge:
        gcs = checker(checker_port, speedup=SPEEDUP)
        try:
            run.wait_for("armed in MANUAL")
            _flying(gcs, MOTORS if output == "motor-test" else PASSTHROUGH)
            run.signal(signal.SIGKILL)
            killed = time.monotonic()
            assert run.wait() == -signal.SIGKILL
            if output == "motor-test":
                gcs.recv("STATUSTEXT", cond=lambda m: m.text == "Motor test timed out!")
                assert not armed(gcs) and servo_outputs(gcs) == [1500] * 8
                assert time.monotonic() - killed < 1.0 / SPEEDUP + 2.0      # 1 s of vehicle time, and slack
            else:
                time.sleep(6.0 / SPEEDUP)
                outputs = servo_outputs(gcs)
                assert outputs[6] != 1500 and outputs[7] != 1500, outputs
                assert servo_functions(gcs) == PASSTHROUGH
        finally:
            gcs.close()


def test_motor_test_is_for_a_law_of_ours(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    mission = short_mission(tmp_path)
    assert cli.main(["run", str(mission), "--controller", "ardusub-guided", "--output", "motor-test"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--output motor-test carries a law's PWMs" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["short.yaml"]


def _from(sysid: int, msg):
    """`msg` as it arrives from `sysid` (packed and parsed: the source is in the header)."""
    mav = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=190)
    return mav.decode(bytearray(msg.pack(mav)))


def test_a_review_reads_motor_tests_as_rows_and_skips_what_ardusub_would_not_apply():
    """A log's DO_MOTOR_TEST: a row of eight PWMs at each command for output 8; a command with a throttle type other
    than PWM (NaN included, as a damaged log may hold) or an output outside 0..7 changes nothing, and breaks nothing."""
    recorder = DiveRecorder()
    recorder.take(0.0, _from(1, mavlink.MAVLink_heartbeat_message(12, 3, 81, 19, 3, 3)))

    def test(wall, output, throttle_type, pwm):
        recorder.take(wall, _from(255, mavlink.MAVLink_command_long_message(1, 1, 209, 0, output, throttle_type, pwm,
                                                                             0.5, 0, 2, 0)))
    for output in range(8):
        test(1.0, output, 1, 1500 + 10 * output)
    test(1.1, 0, float("nan"), 1900)
    test(1.1, 1, 0, 1900)
    test(1.1, float("nan"), 1, 1900)
    test(1.1, 8, 1, 1900)
    test(1.2, 7, 1, 1600)
    wall, pwm = recorder.finish().motor_tests[255]
    assert list(wall) == [1.0, 1.2]
    assert pwm.tolist() == [[1500 + 10 * i for i in range(8)], [1500 + 10 * i for i in range(7)] + [1600]]


@pytest.mark.process
def test_a_disarm_by_another_station_mid_test_stops_the_run_sending_at_once(tmp_path):
    """Another station disarms the vehicle mid-run. A disarmed ArduSub keeps the last test PWMs on the thrusters and
    every further DO_MOTOR_TEST, refused, keeps the test alive (ArduSub/motors.cpp): the run must fall silent the
    moment it sees the refusal or the disarm. Its own log (both directions, stamped as sent and received) shows at
    most the rest of one tick's burst of eight commands after the first sign; the vehicle's test then times out, the
    outputs are neutral, and the run exits non-zero saying why."""
    log = tmp_path / "log"
    mission = short_mission(tmp_path, goto_x=6.0)
    bridge, checker_port = bridge_with_checker(tmp_path, "--start-depth", "1", speedup=SPEEDUP)
    with runner_against(bridge, mission, "--output", "motor-test", "--log", str(log)) as run, bridge:
        gcs = checker(checker_port, speedup=SPEEDUP)
        try:
            run.wait_for("the thrusters through ArduSub's motor test")
            _flying(gcs, MOTORS)
            gcs.send("command_long", 1, 1, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0, 0, 0, 0, 0, 0, 0, 0)
            assert run.wait() != 0
            gcs.recv("STATUSTEXT", cond=lambda m: m.text == "Motor test timed out!")
            assert not armed(gcs) and servo_outputs(gcs) == [1500] * 8
        finally:
            gcs.close()
    assert "stopped sending DO_MOTOR_TEST at once" in run.output, run.output
    sent, first_sign, accepted = [], None, False
    conn = mavutil.mavlink_connection(str(log / "mavlink.tlog"))
    while (m := conn.recv_match()) is not None:
        kind, source = m.get_type(), m.get_srcSystem()
        if kind == "COMMAND_LONG" and m.command == mavlink.MAV_CMD_DO_MOTOR_TEST and source != 1:
            sent.append(m._timestamp)
        elif source == 1 and kind == "COMMAND_ACK" and m.command == mavlink.MAV_CMD_DO_MOTOR_TEST:
            accepted |= m.result == mavlink.MAV_RESULT_ACCEPTED
            if accepted and m.result != mavlink.MAV_RESULT_ACCEPTED and first_sign is None:
                first_sign = m._timestamp
        elif source == 1 and kind == "HEARTBEAT" and accepted and not m.base_mode & 128 and first_sign is None:
            first_sign = m._timestamp
    assert first_sign is not None
    after = [t for t in sent if t > first_sign]
    assert len(after) < 8, f"{len(after)} DO_MOTOR_TEST sent after the vehicle's first refusal or disarm"
