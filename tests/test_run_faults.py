"""Every way a run can end early leaves the vehicle safe, or says plainly that it could not: signals, a limit
crossed, a lost link; refusals before anything is touched; and a dry run that touches nothing."""

from __future__ import annotations

import csv
import signal
import threading
import time
from pathlib import Path

import pytest
from run_helpers import (
    SPEEDUP,
    WAIT,
    RunnerProcess,
    armed,
    assert_left_safe,
    bridge_with_checker,
    checker,
    free_port,
    servo_functions,
    runner_against,
    servo_outputs,
    short_mission,
)
from bridge_helpers import Gcs, mavutil

pytestmark = pytest.mark.process      # starts a process or the bridge (tests/conftest.py)


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_mid_mission_leaves_the_vehicle_safe(tmp_path, signum):
    mission = short_mission(tmp_path, goto_x=6.0)
    bridge, checker_port = bridge_with_checker(tmp_path, "--start-depth", "1")
    with runner_against(bridge, mission) as run, bridge:
        gcs = checker(checker_port)
        try:
            run.wait_for("armed in MANUAL")
            assert servo_functions(gcs) == list(range(51, 59))
            assert servo_outputs(gcs) != [1500] * 8          # flying: passthrough PWMs off neutral
            run.signal(signum)
            assert run.wait() == 128 + signum, run.output
            assert_left_safe(gcs)
        finally:
            gcs.close()
    assert f"stopping: stopped by {signal.Signals(signum).name}" in run.output
    assert "RC overrides on channels 1-8 released" in run.output


def test_a_runner_frozen_past_the_pilot_input_timeout_finds_the_vehicle_disarmed_and_says_what_it_said(tmp_path):
    """SIGSTOP for 2 wall s at speedup 2: 4 s of vehicle time without an override, past FS_PILOT_TIMEOUT (3 s), so
    ArduSub's pilot-input failsafe says "Lost manual control", puts channels 1-6 to neutral and disarms (FS_PILOT_INPUT
    2). Woken, the run stops quoting the vehicle's words (not blaming another station for the outputs the failsafe
    rewrote: seen in CI), restores what it changed and leaves it disarmed."""
    speedup = 2.0
    mission = short_mission(tmp_path, goto_x=6.0)
    bridge, checker_port = bridge_with_checker(tmp_path, "--start-depth", "1", speedup=speedup)
    with runner_against(bridge, mission) as run, bridge:
        gcs = checker(checker_port, speedup=speedup)
        try:
            run.wait_for("armed in MANUAL")
            time.sleep(3.0)                                  # flying (its lead-in, or the mission)
            run.signal(signal.SIGSTOP)
            time.sleep(2.0)
            run.signal(signal.SIGCONT)
            assert run.wait() == 1, run.output
            assert_left_safe(gcs)
        finally:
            gcs.close()
    stop = next(line for line in run.output.splitlines() if "stopping:" in line)
    # Its disarm, or its rewritten outputs, whichever the run reads first, quoting the vehicle's words when they
    # reached it: 4 s of telemetry at 2x overflows the frozen run's UDP socket, which keeps the oldest datagrams, so
    # the text may be lost with the rest, and what the run reads first on waking is that 4 s old backlog (seen in
    # CI: it stopped blaming the link, "a link this slow cannot fly the mission").
    if "vehicle: Lost manual control" in run.output:
        assert "it said just before: 'Lost manual control'" in stop, stop
    else:
        assert "the vehicle was disarmed during the run" in stop, stop
    assert "station is writing" not in stop and "link this slow" not in stop, stop


def _aborted_and_left_safe(tmp_path, mission, bridge_args: tuple[str, ...], *runner_args: str) -> str:
    """Run against a bridge started with `bridge_args`; the run must abort (exit 1) and leave the vehicle safe."""
    bridge, checker_port = bridge_with_checker(tmp_path, "--start-depth", "1", *bridge_args)
    with runner_against(bridge, mission, *runner_args) as run, bridge:
        gcs = checker(checker_port)
        try:
            assert run.wait() == 1, run.output
            assert_left_safe(gcs)
        finally:
            gcs.close()
    return run.output


def test_a_limit_crossed_aborts_and_restores(tmp_path):
    # The mission's path (1 m) is within the flag's limit, which overrides the mission's, so it is accepted; the
    # vehicle, found at 2 m, is past it at the first tick.
    mission = short_mission(tmp_path, limits="limits: {max_depth: 3.0}")
    output = _aborted_and_left_safe(tmp_path, mission, ("--start-depth", "2"), "--max-depth", "1.5")
    assert "limit crossed: depth" in output and "> max_depth 1.5 m" in output


def test_a_lost_link_is_reported_plainly_and_the_next_run_recovers(tmp_path):
    mission = short_mission(tmp_path, goto_x=6.0)
    bridge, checker_port = bridge_with_checker(tmp_path, "--start-depth", "1")
    with bridge:
        with runner_against(bridge, mission) as run:
            run.wait_for("armed in MANUAL")
            time.sleep(0.5)
            bridge.proc.send_signal(signal.SIGSTOP)                # the vehicle stops answering
            try:
                assert run.wait() == 1, run.output
            finally:
                bridge.proc.send_signal(signal.SIGCONT)
        assert "link lost: no telemetry from the vehicle" in run.output
        assert "THE LINK IS GONE" in run.output and "HOLD THEIR LAST COMMAND" in run.output
        gcs = checker(checker_port)
        try:
            assert servo_functions(gcs) == list(range(51, 59))    # not restored: the runner said so
            with runner_against(bridge, short_mission(tmp_path, goto_x=0.4, hold=1.0)) as rerun:
                assert rerun.wait() == 0, rerun.output
            assert_left_safe(gcs)
        finally:
            gcs.close()
    assert "SERVO1_FUNCTION, SERVO2_FUNCTION" in rerun.output and "taken as abandoned" in rerun.output


def test_dry_run_changes_nothing_on_the_vehicle(tmp_path):
    mission = short_mission(tmp_path, goto_x=2.0, hold=1.0)
    bridge, checker_port = bridge_with_checker(tmp_path, "--start-depth", "1")
    rc_seen: list[list[int]] = []
    with runner_against(bridge, mission, "--dry-run", "--log", str(tmp_path / "log")) as run, bridge:
        gcs = checker(checker_port)
        stop = threading.Event()

        def watch_rc():
            while not stop.is_set():
                m = gcs.conn.recv_match(type="RC_CHANNELS", blocking=True, timeout=0.2)
                if m is not None:
                    rc_seen.append([getattr(m, f"chan{i}_raw") for i in range(1, 9)])

        watcher = threading.Thread(target=watch_rc)
        watcher.start()
        try:
            code = run.wait()
            stop.set()
            watcher.join(WAIT)
            assert code == 0, run.output
            assert not armed(gcs)
            assert servo_functions(gcs) == list(range(33, 41))
        finally:
            stop.set()
            gcs.close()
    assert len(rc_seen) > 5 and all(row == [1500] * 8 for row in rc_seen)     # no override ever arrived
    with open(tmp_path / "log" / "ticks.csv") as f:
        rows = list(csv.DictReader(f))
    assert any(float(r["pwm_1"]) != 1500 for r in rows)    # ... though the law computed non-neutral commands
    assert "dry run: no parameter changed, nothing armed, no override sent" in run.output


def test_a_vehicle_armed_by_someone_else_is_refused(tmp_path):
    mission = short_mission(tmp_path)
    # no pilot-input failsafe, which would otherwise disarm the idle vehicle 3 s after the checker armed it
    bridge, checker_port = bridge_with_checker(tmp_path, "--start-depth", "1", "--param", "FS_PILOT_INPUT=0")
    with bridge:
        gcs = checker(checker_port)
        try:
            assert gcs.command(mavutil.mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == 0
            with runner_against(bridge, mission) as run:
                assert run.wait() == 1, run.output
            assert armed(gcs) and servo_functions(gcs) == list(range(33, 41))
        finally:
            gcs.close()
    assert "already armed by someone else" in run.output
    assert "nothing had been changed on the vehicle" in run.output


def _fake_vehicle(port: int, stop: threading.Event) -> None:
    """An ArduPilot quadcopter's heartbeat, answering whoever writes to `port`."""
    conn = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}", source_system=1, source_component=1)
    try:
        while not stop.is_set():
            conn.recv_match(blocking=True, timeout=0.1)
            if conn.clients:                                   # someone wrote to us: answer them
                conn.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_QUADROTOR,
                                        mavutil.mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 81, 0, 3)
    finally:
        conn.close()


def test_a_vehicle_that_is_not_a_sub_is_refused(tmp_path):
    port = free_port()
    stop = threading.Event()
    fake = threading.Thread(target=_fake_vehicle, args=(port, stop))
    fake.start()
    try:
        with RunnerProcess("--target", f"udpout:127.0.0.1:{port}", str(short_mission(tmp_path))) as run:
            assert run.wait() == 1, run.output
    finally:
        stop.set()
        fake.join(WAIT)
    assert "refusing to fly" in run.output and "MAV_TYPE_QUADROTOR" in run.output


def test_no_vehicle_gives_a_clear_message(tmp_path):
    with RunnerProcess("--target", f"udpout:127.0.0.1:{free_port()}", str(short_mission(tmp_path)),
                       "--heartbeat-timeout", "1") as run:
        assert run.wait() == 1, run.output
    assert "no HEARTBEAT from a vehicle on udpout:127.0.0.1:" in run.output and "within 1 s" in run.output


def test_outputs_left_on_passthrough_are_made_neutral_before_anything_else(tmp_path):
    """The hazard after a run lost its link: outputs still on RCIN passthrough, the pilot-input failsafe has put
    channels 1-6 back to neutral but 7 and 8 keep driving two thrusters. The next run must send neutral first (not
    refuse on seeing RC7/RC8 off neutral and leave them running), then fly and restore everything."""
    mission = short_mission(tmp_path, goto_x=0.4, hold=1.0)
    bridge, checker_port = bridge_with_checker(tmp_path, "--start-depth", "1")
    with bridge:
        gcs = checker(checker_port)
        previous = Gcs(checker_port, speedup=SPEEDUP, sysid=255)     # the earlier run, as the GCS sysid
        try:
            previous.connect()
            for n in range(1, 9):
                assert previous.set_param(f"SERVO{n}_FUNCTION", 50 + n).param_value == 50 + n
            for _ in range(5):
                previous.rc_override([1500] * 6 + [1600, 1400])
                time.sleep(0.02)
            previous.close()                                             # ... and then its link was lost
            gcs.heartbeat()                            # the port answers its latest sender: the checker again
            deadline = time.monotonic() + WAIT
            while servo_outputs(gcs)[:6] != [1500] * 6 and time.monotonic() < deadline:
                time.sleep(0.1)                                          # pilot-input failsafe: 1-6 neutral
            assert servo_outputs(gcs) == [1500] * 6 + [1600, 1400]      # 7 and 8 still driving
            with runner_against(bridge, mission) as run:
                assert run.wait() == 0, run.output
            assert_left_safe(gcs)
        finally:
            gcs.close()
    assert "taken as abandoned" in run.output


def test_overrides_the_vehicle_ignores_stop_the_run_before_any_output_is_switched(tmp_path):
    """RC_OVERRIDE_TIME = 0 (ArduSub then ignores every override): the runner must not switch the outputs to
    passthrough and arm a vehicle it cannot command."""
    mission = short_mission(tmp_path, goto_x=0.4, hold=1.0)
    output = _aborted_and_left_safe(tmp_path, mission, ("--param", "RC_OVERRIDE_TIME=0"))
    assert "the vehicle does not apply our RC overrides" in output
    assert "SERVO1..8_FUNCTION set to RCIN1..8 passthrough" not in output


def test_a_dry_run_that_would_have_aborted_does_not_exit_0(tmp_path):
    """A dry run acts on no limit, but one it would have acted on is its result: exit 1, the limit named, never a
    clean "completed" (the vehicle sits still while the reference moves away: 5 cm is crossed within seconds)."""
    mission = short_mission(tmp_path, goto_x=1.0, hold=1.0)
    with RunnerProcess(str(mission), "--dry-run", "--speedup", "10", "--max-tracking-error", "0.05") as run:
        code = run.wait()
    assert code == 1, run.output
    assert "dry run: would abort here: tracking error" in run.output
    assert "completed, exit 1: dry run: it would have aborted (limit crossed: tracking error" in run.output


def _children(pid: int) -> list[int]:
    """Processes whose parent is `pid` (from /proc)."""
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            found.append(int(stat.parent.name))
    return found


def test_a_runner_killed_outright_takes_its_built_in_vehicle_with_it(tmp_path):
    """The built-in vehicle runs in a child process: SIGKILL of the runner (no stop runs) still ends it, by the
    kernel's parent-death signal, so no simulated vehicle is left running on its port."""
    mission = short_mission(tmp_path, goto_x=4.0, hold=5.0)
    with RunnerProcess(str(mission), "--speedup", "2") as run:
        run.wait_for("armed in MANUAL")
        vehicles = _children(run.proc.pid)
        assert vehicles, "no child process: the built-in vehicle should run in one"
        run.signal(signal.SIGKILL)
        run.proc.wait(WAIT)
        deadline = time.monotonic() + WAIT
        while any(Path(f"/proc/{pid}").exists() and "Z" not in _state(pid) for pid in vehicles):
            assert time.monotonic() < deadline, f"the vehicle's process outlived the runner: {vehicles}"
            time.sleep(0.1)


def _state(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return "Z"
