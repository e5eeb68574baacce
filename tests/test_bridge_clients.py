"""Independent clients take the bridge for ArduSub: MAVProxy (its own console, fed on stdin) and MAVSDK (its
native library), each in its own process against `rov-mav sim-bridge` over UDP. Both are test dependencies
(mavproxy, mavsdk >= 4): these tests fail, not skip, without them."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import pytest
from bridge_helpers import MAVPROXY, WAIT, BridgeProcess, Console

pytestmark = pytest.mark.process      # starts a process or the bridge (tests/conftest.py)

def test_mavproxy_sees_ardusub_changes_mode_arms_and_sets_a_parameter(tmp_path):
    # real time: MAVProxy sends its GCS heartbeat at 1 Hz of wall time
    with BridgeProcess(tmp_path, speedup=1.0) as bridge:
        console = Console([MAVPROXY, f"--master=udpout:127.0.0.1:{bridge.port}", f"--state-basedir={tmp_path}"],
                          tmp_path / "mavproxy.out", tmp_path)
        try:
            console.expect("Detected vehicle 1:1")
            console.expect("Mode MANUAL")                  # mode 19 named from ArduSub's table
            console.expect("Received")                     # the parameter download finished
            console.send("status HEARTBEAT")
            console.expect("type : 12, autopilot : 3")
            console.send("mode ALT_HOLD")
            console.expect("DO_SET_MODE: ACCEPTED")
            console.expect("Mode ALT_HOLD")
            console.send("arm throttle")
            console.expect("COMPONENT_ARM_DISARM: ACCEPTED")
            console.expect("ARMED")
            console.send("param set FS_GCS_TIMEOUT 7.5")
            console.poll("param show FS_GCS_TIMEOUT", "FS_GCS_TIMEOUT   7.5")
            console.send("disarm")
            console.expect("DISARMED")
        finally:
            console.close("exit")


MAVSDK_SCRIPT = """
import json, math, sys, time
from mavsdk import ComponentType, Configuration, Mavsdk
from mavsdk.plugins.action import Action
from mavsdk.plugins.param import Param
from mavsdk.plugins.telemetry import Telemetry

sdk = Mavsdk(Configuration.create_with_component_type(ComponentType.GROUND_STATION))
sdk.add_any_connection("udpout://127.0.0.1:" + sys.argv[1])
system = sdk.first_autopilot(20.0)
out = {"autopilot": system.autopilot_type().name, "vehicle": system.vehicle_type().name}
telemetry = Telemetry(system)
deadline = time.monotonic() + 20
while math.isnan(telemetry.attitude_euler().roll_deg) and time.monotonic() < deadline:
    time.sleep(0.1)
time.sleep(1.0)
angles, rates = telemetry.attitude_euler(), telemetry.attitude_angular_velocity_body()
out["roll_deg"], out["pitch_deg"], out["yaw_rate"] = angles.roll_deg, angles.pitch_deg, rates.yaw_rad_s
action = Action(system)
action.arm()
deadline = time.monotonic() + 20
while not telemetry.armed() and time.monotonic() < deadline:
    time.sleep(0.1)
out["armed"] = telemetry.armed()
out["fs_gcs_timeout"] = Param(system).get_param_float("FS_GCS_TIMEOUT")
action.disarm()
print(json.dumps(out), flush=True)
"""


def test_mavsdk_connects_reads_attitude_and_arms(tmp_path):
    env = tmp_path / "environment.yaml"
    env.write_text("environment:\n  disturbance: [0, 0, 0, 0, 0, 0.6]\n")    # a steady yaw moment
    with BridgeProcess(tmp_path, "--environment", str(env), "--start-depth", "3") as bridge:
        r = subprocess.run([sys.executable, "-c", MAVSDK_SCRIPT, str(bridge.port)], capture_output=True, text=True,
                           timeout=120)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout.strip().splitlines()[-1])
    assert (out["autopilot"], out["vehicle"], out["armed"]) == ("ARDUPILOT", "SUBMARINE", True)
    assert out["fs_gcs_timeout"] == 5.0
    # the yaw rate settles where quadratic yaw drag 1.5 r|r| balances 0.6 N m
    assert out["yaw_rate"] == pytest.approx(0.4**0.5, rel=0.03)
    assert abs(out["roll_deg"]) < 0.5 and abs(out["pitch_deg"]) < 0.5
