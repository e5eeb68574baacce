"""Upload with MAVProxy, fly with rov-mav: MAVProxy (an independent client, its own process) loads a mission into
`rov-mav sim-bridge` with `wp load`; `rov-mav run --mission-from-vehicle` downloads it and flies it. The reference
it flies is the one the same items give as a QGroundControl plan, the vehicle ends where the last waypoint is, and
it is left safe. A mission with a takeoff item is refused before anything moves."""

from __future__ import annotations

import json

import numpy as np
import pytest
from plan_helpers import HOME, NAV_TAKEOFF, simple_item, waypoint, wpl, write_plan
from run_helpers import (
    RunnerProcess,
    assert_left_safe,
    bridge_with_checker,
    checker,
    free_port,
    servo_functions,
)
from bridge_helpers import MAVPROXY, Console

from rov_mav.mission.loader import load

pytestmark = pytest.mark.process      # starts a process or the bridge (tests/conftest.py)

# 4 m north, 4 m east and 1 m deeper, back west; 3 s holds; no yaw (ArduSub would not keep one).
ITEMS = [waypoint(1, 47.3977419, 8.5455940, -2.0),
         waypoint(2, 47.3977779, 8.5455940, -2.0, hold=3),
         waypoint(3, 47.3977779, 8.5456470, -3.0, hold=3),
         waypoint(4, 47.3977779, 8.5455940, -3.0)]
SPEED = 0.3
ARRIVAL = 0.30            # m: where the vehicle ends, against the last waypoint
SLOWER = 5.0              # the bridge's speedup: at 10x, with MAVProxy on a third link, a loaded CI machine tipped
                          # the vehicle past 15 deg (measured once in a full suite)


def test_mavproxy_uploads_a_mission_and_run_flies_it_from_the_vehicle(tmp_path):
    plan = write_plan(tmp_path / "dive.plan", ITEMS, cruise_speed=SPEED)
    expected = load(plan)
    (tmp_path / "dive.txt").write_text(wpl(ITEMS))
    (tmp_path / "takeoff.txt").write_text(wpl([simple_item(1, NAV_TAKEOFF, [0, 0, 0, None, *HOME[:2], 5])]
                                              + ITEMS))
    mavproxy_port = free_port()
    bridge, checker_port = bridge_with_checker(tmp_path, "--listen", f"udpin:127.0.0.1:{mavproxy_port}",
                                               "--origin", f"{HOME[0]},{HOME[1]},0", "--start-depth", "2",
                                               speedup=SLOWER)
    with bridge:
        gcs = checker(checker_port, speedup=SLOWER)
        console = Console([MAVPROXY, f"--master=udpout:127.0.0.1:{mavproxy_port}", f"--state-basedir={tmp_path}"],
                          tmp_path / "mavproxy.out", tmp_path)
        try:
            console.expect("Detected vehicle 1:1")
            run_args = ("--target", f"udpout:127.0.0.1:{bridge.port}", "--mission-from-vehicle", "--rerun", "off",
                        "--heartbeat-timeout", "60")
            # a mission with a takeoff: refused, and nothing on the vehicle changed
            console.send("wp load takeoff.txt")
            console.expect("Got MISSION_ACK: TYPE_MISSION: ACCEPTED")
            with RunnerProcess(*run_args) as run:
                assert run.wait() == 2, run.output
            assert "vehicle item 1 (NAV_TAKEOFF)" in run.output and "Traceback" not in run.output
            assert servo_functions(gcs) == list(range(33, 41))
            # the mission as planned
            console.send("wp load dive.txt")
            console.expect("Got MISSION_ACK: TYPE_MISSION: ACCEPTED")
            console.send("wp list")
            console.expect("Saved 5 waypoints")
        finally:
            console.close("exit")
        metrics_path = tmp_path / "metrics.json"
        try:
            with RunnerProcess(*run_args, "--plan-speed", str(SPEED), "--metrics", str(metrics_path),
                               "--log", str(tmp_path / "log")) as run:
                assert run.wait() == 0, run.output
            assert_left_safe(gcs)
        finally:
            gcs.close()
    assert f"mission downloaded from vehicle 1: {len(expected.segments)} segments" in run.output
    ticks = np.genfromtxt(tmp_path / "log" / "ticks.csv", delimiter=",", names=True)
    flown = ticks[ticks["t"] >= 0]
    reference = expected.reference(flown["t"])
    for column, index in (("x_d", 0), ("y_d", 1), ("z_d", 2), ("psi_d", 5)):
        assert np.abs(flown[column] - reference[:, index]).max() < 1e-3, column
    end = np.array([flown["x"][-1], flown["y"][-1], flown["z"][-1]])
    last = expected.segments[-1].p1[:3]
    metrics = json.loads(metrics_path.read_text())
    print(f"vehicle mission: {metrics['duration_s']:.1f} s flown, RMS {metrics['rms_position_error_m'] * 100:.2f} cm, "
          f"ended {np.linalg.norm(end - last) * 100:.1f} cm from the last waypoint")
    assert metrics["completed"] and metrics["duration_s"] >= expected.duration - 0.1
    assert np.linalg.norm(end - last) < ARRIVAL
