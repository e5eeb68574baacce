"""`rov-mav run` against ArduPilot's own ArduSub SITL (ARDUSUB_SITL): the real autopilot's parameters, override
handling, passthrough and arming. One SITL instance for the module (its EKF needs ~40 s of simulated time for a
position), runs one after another on its SERIAL1, an independent checker on SERIAL0."""

from __future__ import annotations

import json
import signal
import time
from pathlib import Path

import numpy as np
import pytest
from run_helpers import RunnerProcess, short_mission
from sitl_helpers import SPEEDUP, Checker, Sitl

from rov_mav.review.logdir import read_ticks

pytestmark = pytest.mark.process      # starts a process or the bridge (tests/conftest.py)

RATE = 50.0                    # Hz: run's default --rate
POSITION_WAIT = 120.0          # wall s for the EKF's first position on a loaded machine
SITL_VEHICLE = Path(__file__).resolve().parents[1] / "vehicles" / "ardusub_sitl.yaml"


@pytest.fixture(scope="module")
def sitl(tmp_path_factory):
    with Sitl(tmp_path_factory.mktemp("sitl")) as instance:
        instance.wait_for_port(instance.port0)
        checker = Checker(instance.port0)
        try:
            checker.wait_for_position(POSITION_WAIT)
            yield instance, checker
        finally:
            checker.close()


def _run(sitl: Sitl, mission, *args: str) -> RunnerProcess:
    return RunnerProcess("--target", f"tcp:127.0.0.1:{sitl.port1}", str(mission), "--rerun", "off", *args)


def test_sitl_runs_faster_than_the_wall(sitl):
    """Every timeout in these tests is vehicle time, so a machine that holds less than SPEEDUP only makes them
    slower; but SITL must run ahead of the wall, or --speedup was not taken."""
    _, checker = sitl
    achieved = checker.achieved_speedup()
    print(f"SITL speedup achieved: {achieved:.2f} (asked {SPEEDUP:g})")
    assert 1.2 < achieved < SPEEDUP * 1.1


def test_a_mission_on_sitl_completes_and_leaves_the_vehicle_safe(sitl, tmp_path):
    instance, checker = sitl
    metrics = tmp_path / "metrics.json"
    with _run(instance, short_mission(tmp_path, goto_x=2.0, hold=3.0), "--metrics", str(metrics)) as run:
        assert run.wait() == 0, run.output
    checker.assert_left_safe()
    assert "SYSID_MYGCS = 255" in run.output             # ArduSub 4.5's name for the GCS sysid
    assert "completed" in run.output
    # Each ATTITUDE pairs with its LOCAL_POSITION_NED (ArduSub stamps both alike): no state is lost to pairing.
    # Measured on SERIAL1 at 4x: 37-38 Hz of the 50 asked, with pairing by stamps and without.
    loop = json.loads(metrics.read_text())["loop"]
    print(f"control rate on SITL: {loop['control_rate_hz']:.1f} Hz")
    assert loop["control_rate_hz"] > 0.6 * RATE


def test_sigterm_mid_mission_on_sitl_leaves_it_safe(sitl, tmp_path):
    instance, checker = sitl
    with _run(instance, short_mission(tmp_path, goto_x=4.0, hold=30.0)) as run:
        run.wait_for("armed in MANUAL")
        assert checker.servo_functions() == list(range(51, 59))
        run.signal(signal.SIGTERM)
        assert run.wait() == 128 + signal.SIGTERM, run.output
    checker.assert_left_safe()


def test_a_dry_run_on_sitl_changes_nothing(sitl, tmp_path):
    instance, checker = sitl
    before = checker.servo_functions()
    with _run(instance, short_mission(tmp_path, goto_x=0.5, hold=1.0), "--dry-run") as run:
        assert run.wait() == 0, run.output
    assert checker.servo_functions() == before == list(range(33, 41))
    assert not checker.armed() and checker.param("SYSID_MYGCS") == 255
    rc = checker.fresh("RC_CHANNELS")
    assert [getattr(rc, f"chan{i}_raw") for i in range(1, 9)] == [1500] * 8     # no override ever arrived
    assert "dry run: no parameter changed, nothing armed, no override sent" in run.output


def test_sitls_own_vehicle_file_holds_pitch_on_sitl(sitl, tmp_path):
    """vehicles/ardusub_sitl.yaml is SIM_Submarine's vehicle: flown with it, the allocation puts no pitch moment on
    SITL's hull where its horizontal thrusters have no pitch arm (the default BlueROV2 model does: measured 0.3 deg
    RMS of pitch on the square, this file 0.006 deg). The median is robust to a loaded machine's stalls."""
    instance, checker = sitl
    with _run(instance, short_mission(tmp_path, goto_x=2.0, hold=3.0), "--vehicle", str(SITL_VEHICLE),
              "--log", str(tmp_path / "log")) as run:
        assert run.wait() == 0, run.output
    checker.assert_left_safe()
    ticks, _ = read_ticks(tmp_path / "log" / "ticks.csv")
    flown = ticks["t"] >= 0.0
    pitch = np.degrees(np.abs(ticks["theta"][flown] - ticks["theta_d"][flown]))
    print(f"pitch error on SITL with its own vehicle file: median {np.median(pitch):.4f} deg")
    assert np.median(pitch) < 0.03


def test_guided_on_sitl_flies_the_mission_and_leaves_it_as_found(sitl, tmp_path):
    """`--controller ardusub-guided`: ArduSub's own position controller flies the reference; nothing but the mode
    and arming change, and both are put back."""
    instance, checker = sitl
    metrics = tmp_path / "metrics.json"
    with _run(instance, short_mission(tmp_path, goto_x=2.0, hold=3.0), "--controller", "ardusub-guided",
              "--metrics", str(metrics)) as run:
        run.wait_for("armed in GUIDED")
        assert checker.fresh("HEARTBEAT").custom_mode == 4
        assert run.wait() == 0, run.output
    checker.assert_left_safe()
    assert checker.fresh("HEARTBEAT").custom_mode == 19 and checker.param("SYSID_MYGCS") == 255
    result = json.loads(metrics.read_text())
    print(f"GUIDED on SITL, short mission: RMS {result['rms_position_error_m'] * 100:.1f} cm")
    assert result["completed"] and result["rms_position_error_m"] < 0.25


def test_motor_test_on_sitl_killed_outright_stops_and_disarms(sitl, tmp_path):
    """--output motor-test on the real autopilot: MAV_CMD_DO_MOTOR_TEST accepted (board order, 0-based outputs, raw
    PWM, as measured on 4.5.3) with the outputs left on their motors; then SIGKILL mid-mission: ArduSub itself ends
    the test ("Motor test timed out!"), disarms, outputs neutral."""
    instance, checker = sitl
    with _run(instance, short_mission(tmp_path, goto_x=4.0, hold=30.0), "--output", "motor-test") as run:
        run.wait_for("the thrusters through ArduSub's motor test")
        assert checker.servo_functions() == list(range(33, 41))
        deadline = time.monotonic() + 30.0
        while checker.servo_outputs() == [1500] * 8:
            assert time.monotonic() < deadline, "the outputs never left neutral"
        run.signal(signal.SIGKILL)
        assert run.wait() == -signal.SIGKILL
    statustext = checker.conn.recv_match(type="STATUSTEXT", blocking=True, timeout=10.0,
                                         condition="STATUSTEXT.text == 'Motor test timed out!'")
    assert statustext is not None
    checker.assert_left_safe()
