"""`rov-mav run --controller ardusub-guided`: the mission's reference streamed to the vehicle's own GUIDED mode
(SET_POSITION_TARGET_LOCAL_NED), end to end against a bridge process, with a checker on the bridge's second link;
and the commands that cannot fly it refuse it in one line."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest
from pymavlink import mavutil
from run_helpers import (
    ROV_MAV,
    RunnerProcess,
    assert_left_safe,
    bridge_with_checker,
    checker,
    fresh,
    servo_outputs,
)

from rov_mav.flight.session.link import GUIDED, MANUAL

pytestmark = pytest.mark.process      # starts a process or the bridge (tests/conftest.py)

SPEEDUP = 5.0                  # the 60 s square plus its lead-in in about 15 s of wall time
RMS_LIMIT = 0.25               # m: measured 0.16 (ArduSub's gains on the bridge's BlueROV2, the square's current)
SMALL_SQUARE = """name: small_square
start: {position: [0.0, 0.0, 1.0], heading: 0.0}
ramp_time: 2.0
path:
  - {goto: [2.0, 0.0, 1.0], speed: 0.2}
  - {hold: 3, heading: 90 deg}
  - {goto: [2.0, 2.0, 1.0], speed: 0.2}
  - {hold: 3, heading: 180 deg}
  - {goto: [0.0, 2.0, 1.0], speed: 0.2}
  - {hold: 3, heading: -90 deg}
  - {goto: [0.0, 0.0, 1.0], speed: 0.2}
  - {hold: 3, heading: 0 deg}
environment:
  disturbance: [-1.0, 1.0, 2.0, 0.1, 0.1, 0.0]
limits: {max_depth: 3.0, max_tracking_error: 1.5, max_thrust: 40.0}
"""


def test_guided_flies_the_square_on_the_bridge_and_leaves_it_as_found(tmp_path):
    mission = tmp_path / "small_square.yaml"
    mission.write_text(SMALL_SQUARE)
    bridge, checker_port = bridge_with_checker(tmp_path, "--environment", str(mission), "--start-depth", "1",
                                               speedup=SPEEDUP)
    log, metrics_path = tmp_path / "log", tmp_path / "metrics.json"
    with RunnerProcess("--target", f"udpout:127.0.0.1:{bridge.port}", str(mission), "--controller", "ardusub-guided",
                       "--guided-rate", "10", "--metrics", str(metrics_path), "--log", str(log), "--rerun", "off",
                       "--heartbeat-timeout", "60") as run, bridge:
        gcs = checker(checker_port, SPEEDUP)
        try:
            run.wait_for("armed in GUIDED")
            flying_mode = fresh(gcs, "HEARTBEAT").custom_mode
            flying = servo_outputs(gcs)
            assert run.wait() == 0, run.output
            assert_left_safe(gcs)                       # disarmed, neutral, SERVO1..8_FUNCTION on the motors
            assert fresh(gcs, "HEARTBEAT").custom_mode == MANUAL
        finally:
            gcs.close()
    assert flying_mode == GUIDED and flying != [1500] * 8    # the vehicle's own mixer drove the thrusters
    metrics = json.loads(metrics_path.read_text())
    assert metrics["completed"] and metrics["duration_s"] >= 59.9, run.output
    assert metrics["rms_position_error_m"] <= RMS_LIMIT, run.output
    print(f"small square, GUIDED on the bridge at {SPEEDUP:g}x: RMS {metrics['rms_position_error_m'] * 100:.1f} cm, "
          f"max {metrics['max_position_error_m'] * 100:.1f} cm")
    # what went to the vehicle: position targets at the chosen rate, and no parameter change at all
    tlog = mavutil.mavlink_connection(str(log / "mavlink.tlog"))
    targets, param_sets, modes = [], 0, []
    while (m := tlog.recv_match()) is not None:
        if m.get_type() == "SET_POSITION_TARGET_LOCAL_NED":
            targets.append(m)
        elif m.get_type() == "PARAM_SET":
            param_sets += 1
    assert param_sets == 0
    # ArduSub 4.7.2 (the bridge's default) takes the acceleration too: only the yaw rate is left out
    assert "ArduSub 4.7.2: GUIDED targets with the acceleration fed forward" in run.output
    assert {t.coordinate_frame for t in targets} == {mavutil.mavlink.MAV_FRAME_LOCAL_NED}
    masks = [t.type_mask for t in targets]
    assert set(masks) <= {0x800, 0x9C0} and masks.count(0x800) > 0.9 * len(masks)   # holds (stopping) without
    assert max(abs(t.afx) + abs(t.afy) for t in targets) > 0.0      # the square's corners
    span = (targets[-1].time_boot_ms - targets[0].time_boot_ms) / 1000.0
    assert abs((len(targets) - 1) / span - 10.0) < 0.5
    # the log keeps a law's columns (NaN where there is no law) and `analyze` reads it
    header = (log / "ticks.csv").read_text().splitlines()[0].split(",")
    assert {"tau_hat_X", "pwm_8", "x_d"} <= set(header)
    analyze = subprocess.run([ROV_MAV, "analyze", str(log)], capture_output=True, text=True, timeout=120)
    assert analyze.returncode == 0, analyze.stdout + analyze.stderr


def test_simulate_and_tune_refuse_guided_in_one_line():
    square = str(Path(__file__).resolve().parents[1] / "missions" / "square.yaml")
    for command in (["simulate", square], ["tune", square]):
        done = subprocess.run([ROV_MAV, *command, "--controller", "ardusub-guided"], capture_output=True, text=True,
                              timeout=60)
        assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1, done.stderr
        assert "only `rov-mav run`" in done.stderr
