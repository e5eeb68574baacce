"""A run on a link it shares, as on a real BlueROV2 whose companion router shows every station's traffic to every
other: a second run, another station's RC overrides, a live driver of passthrough outputs. The run touches only what
is provably its own or abandoned, and hands the vehicle over when someone else drives."""

from __future__ import annotations

import re
import time
from contextlib import contextmanager

import pytest
from mavlink_hub import Hub
from run_helpers import (
    SPEEDUP,
    WAIT,
    RunnerProcess,
    armed,
    assert_left_safe,
    bridge_with_checker,
    checker,
    runner_against,
    servo_functions,
    servo_outputs,
    short_mission,
)
from bridge_helpers import Gcs

pytestmark = pytest.mark.process      # starts a process or the bridge (tests/conftest.py)

HANDOVER_LIMIT = 0.5          # vehicle s from a driver seen to the vehicle handed over


def _run(hub: Hub, mission, *args: str) -> RunnerProcess:
    return RunnerProcess("--target", f"udpout:127.0.0.1:{hub.port}", str(mission), "--heartbeat-timeout", "60",
                         *args)


def _station(hub: Hub, sysid: int = 255) -> Gcs:
    """Another station on the router (the pilot's ground station is sysid 255, component 190, like us)."""
    station = Gcs(hub.port, speedup=SPEEDUP, sysid=sysid, rate=10.0)
    station.connect()
    return station


@contextmanager
def _shared_link(tmp_path, speedup: float = SPEEDUP):
    """A bridge behind a router (the hub) and an independent checker on the bridge's second port."""
    bridge, checker_port = bridge_with_checker(tmp_path, "--start-depth", "1", speedup=speedup)
    with bridge, Hub(bridge.port) as hub:
        gcs = checker(checker_port)
        try:
            yield hub, gcs
        finally:
            gcs.close()


@contextmanager
def _closing(station: Gcs):
    try:
        yield station
    finally:
        station.close()


def _handover_time(output: str) -> float:
    found = re.search(r"handed over ([0-9.]+) s of vehicle time", output)
    assert found, output
    return float(found.group(1))


def test_a_second_run_refuses_in_one_line_and_the_first_completes_unaffected(tmp_path):
    # Two runners and a bridge on two cores: at speedup 4 the first run holds its control rate while the second
    # starts, so its tracking can be compared with a run alone; it is still flying when the second has decided.
    mission = short_mission(tmp_path, hold=60.0)
    with _shared_link(tmp_path, speedup=4.0) as (hub, gcs):
        with _run(hub, mission) as first:
            first.wait_for("armed in MANUAL")
            with _run(hub, mission) as second:
                assert second.wait() == 1, second.output
            assert first.proc.poll() is None, "the first run ended before the second had decided"
            assert first.wait() == 0, first.output
        assert_left_safe(gcs)
    refusal = [line for line in second.output.splitlines() if "stopping: refusing to take the vehicle" in line]
    assert len(refusal) == 1 and "already armed" in refusal[0] and "RC_CHANNELS_OVERRIDE" in refusal[0], second.output
    assert "nothing had been changed on the vehicle" in second.output
    # Unaffected: completed and tracked as a run alone does
    assert "completed" in first.output and "disarmed during" not in first.output
    rms = re.search(r"position error RMS ([0-9.]+) cm", first.output)
    assert rms and float(rms.group(1)) < 1.0, first.output


def test_another_stations_overrides_mid_run_hand_the_vehicle_over(tmp_path):
    mission = short_mission(tmp_path, hold=60.0)
    with _shared_link(tmp_path) as (hub, gcs):
        with _run(hub, mission) as run:
            run.wait_for("armed in MANUAL")
            time.sleep(1.0)
            with _closing(_station(hub)) as intruder:
                intruder.override = [1500] * 8
                intruder.start_pump()
                assert run.wait() == 3, run.output
        assert armed(gcs) and servo_functions(gcs) == list(range(33, 41))   # armed, on its motors
    stop = next(line for line in run.output.splitlines() if "stopping:" in line)
    assert "station sysid 255 component 190" in stop and ("another station took over the thrusters" in stop or
                                                          "a ground station appeared mid-run" in stop), stop
    assert _handover_time(run.output) <= HANDOVER_LIMIT


def test_passthrough_outputs_with_a_live_driver_are_not_touched(tmp_path):
    mission = short_mission(tmp_path)
    with _shared_link(tmp_path) as (hub, gcs), _closing(_station(hub)) as driver:
        for n in range(1, 9):
            assert driver.set_param(f"SERVO{n}_FUNCTION", 50 + n).param_value == 50 + n
        driver.override = [1520] * 8
        driver.start_pump()
        with _run(hub, mission) as run:
            assert run.wait() == 1, run.output
        assert servo_functions(gcs) == list(range(51, 59)) and not armed(gcs)
    assert "another station is driving it" in run.output and "Nothing was sent to it" in run.output
    assert "nothing had been changed on the vehicle" in run.output and "taken as abandoned" not in run.output


def _pilot(hub: Hub) -> Gcs:
    """The pilot's ground station with a joystick at rest: heartbeats and MANUAL_CONTROL at 25 Hz, GCS sysid 255."""
    pilot = _station(hub)
    pilot.rate = 25.0
    pilot.joystick = (0, 0, 500, 0)
    pilot.start_pump()
    return pilot


def test_a_run_coexists_with_a_pilot_station_whose_joystick_rests(tmp_path):
    mission = short_mission(tmp_path)
    with _shared_link(tmp_path) as (hub, gcs), _closing(_pilot(hub)):
        with _run(hub, mission) as run:
            assert run.wait() == 0, run.output
        assert_left_safe(gcs)
        assert gcs.get_param("MAV_GCS_SYSID").param_value == 255
    assert "took the GCS role for this run: speaking as sysid 254" in run.output
    assert "restored MAV_GCS_SYSID=255" in run.output and "completed" in run.output


def test_the_pilot_moving_the_joystick_takes_the_vehicle_over(tmp_path):
    mission = short_mission(tmp_path, hold=60.0)
    with _shared_link(tmp_path) as (hub, gcs), _closing(_pilot(hub)) as pilot:
        with _run(hub, mission) as run:
            run.wait_for("armed in MANUAL")
            time.sleep(1.0)
            pilot.joystick = (600, 0, 500, 0)                    # forward
            assert run.wait() == 3, run.output
        assert armed(gcs) and servo_functions(gcs) == list(range(33, 41))
        assert gcs.get_param("MAV_GCS_SYSID").param_value == 255
        deadline = time.monotonic() + WAIT
        while (outputs := servo_outputs(gcs)) == [1500] * 8 and time.monotonic() < deadline:
            time.sleep(0.1)
        assert outputs != [1500] * 8            # ArduSub's mixer now follows the pilot's joystick
    assert "pilot takeover: station sysid 255 component 190" in run.output
    assert _handover_time(run.output) <= HANDOVER_LIMIT


def test_with_motor_test_a_pilot_takeover_leaves_the_vehicle_disarmed_for_the_pilot_to_arm(tmp_path):
    """--output motor-test: ArduSub's motor test runs no mixer, and only its timeout ends it, with a disarm. So the
    handover stops the test: within a second of vehicle time the vehicle is disarmed, neutral, on its motors, the GCS
    sysid back to the pilot's, and the run says the pilot must arm it."""
    mission = short_mission(tmp_path, hold=60.0)
    with _shared_link(tmp_path, speedup=3.0) as (hub, gcs), _closing(_pilot(hub)) as pilot:
        with _run(hub, mission, "--output", "motor-test") as run:
            run.wait_for("the thrusters through ArduSub's motor test")
            time.sleep(1.0)
            pilot.joystick = (600, 0, 500, 0)                    # forward
            assert run.wait() == 3, run.output
        deadline = time.monotonic() + 5.0          # the checker, unread during the run, drained by each read
        while armed(gcs):
            assert time.monotonic() < deadline, "still armed 5 s after the handover"
        assert servo_outputs(gcs) == [1500] * 8
        assert servo_functions(gcs) == list(range(33, 41))
        assert gcs.get_param("MAV_GCS_SYSID").param_value == 255
    assert "pilot takeover: station sysid 255 component 190" in run.output
    assert "arm it again to drive" in run.output and _handover_time(run.output) <= HANDOVER_LIMIT


def test_a_pilot_joining_mid_dive_on_another_link_of_the_vehicle_is_handed_the_vehicle(tmp_path):
    """missions-like: a run flying; at mission t ~ 10 s a pilot station (sysid 255, component 190: the run's own
    ids, so the vehicle forwards it nothing) on its own link of the vehicle, silent until then, sends MANUAL_CONTROL
    x = 600 at 25 Hz. The run sees it only in what the vehicle reports (its joystick interleaved with our overrides in
    SERVO_OUTPUT_RAW and RC_CHANNELS) and hands over (exit 3); without that it flew on (measured: 8 s, until
    stopped)."""
    speedup = 5.0
    mission = short_mission(tmp_path, goto_x=30.0)
    bridge, pilot_port = bridge_with_checker(tmp_path, "--start-depth", "1", speedup=speedup)
    with runner_against(bridge, mission) as run, bridge:
        run.wait_for("armed in MANUAL")
        run.wait_for("t    10.0 s", timeout=120.0)
        pilot = Gcs(pilot_port, speedup, sysid=255, rate=25.0)
        try:
            pilot.joystick = (600, 0, 500, 0)
            pilot.heartbeats = False                    # silent but for its joystick
            pilot.start_pump()
            assert run.wait() == 3, run.output
        finally:
            pilot.close()
    stop = next(line for line in run.output.splitlines() if "stopping:" in line)
    assert "not what this run sends" in stop, stop
    assert _handover_time(run.output) <= HANDOVER_LIMIT
    stopped = float(re.search(r"\[ *([0-9.]+)\] stopping", run.output).group(1))
    assert 10.0 < stopped < 15.0, run.output     # from the status line at 10 s: the pilot's start, then the verdict


def test_a_ground_station_whose_heartbeat_the_vehicle_forwards_is_handed_the_vehicle_before_its_joystick(tmp_path):
    """The same dive, the pilot's station on component 191: the vehicle forwards its HEARTBEAT to the run's link
    (`MAVLink_routing::check_and_forward`), so the run sees a ground station appear on its GCS sysid mid-run and
    hands over at once (exit 3), before any joystick, within HANDOVER_LIMIT of vehicle time."""
    speedup = 5.0
    mission = short_mission(tmp_path, goto_x=30.0)
    bridge, pilot_port = bridge_with_checker(tmp_path, "--start-depth", "1", speedup=speedup)
    with runner_against(bridge, mission) as run, bridge:
        run.wait_for("t    10.0 s", timeout=120.0)
        pilot = Gcs(pilot_port, speedup, sysid=255)
        pilot.conn.mav.srcComponent = 191
        try:
            pilot.start_pump()                          # heartbeats only
            assert run.wait() == 3, run.output
        finally:
            pilot.close()
    stop = next(line for line in run.output.splitlines() if "stopping:" in line)
    assert "a ground station appeared mid-run on our GCS sysid 255" in stop and "component 191" in stop, stop
    assert _handover_time(run.output) <= HANDOVER_LIMIT
