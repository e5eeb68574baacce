"""A run over a degraded link (the bridge's --link-faults on the runner's link only; the checker's link stays clean):
it starts and completes under 30 % loss each way, a cut longer than the link timeout aborts it to neutral, and a
safe stop whose restore is never confirmed exits non-zero naming the step."""

from __future__ import annotations

import re
import socket

import pytest
from run_helpers import (
    RUN_WAIT,
    RunnerProcess,
    assert_left_safe,
    bridge_with_checker,
    checker,
    short_mission,
)

pytestmark = pytest.mark.process      # starts a process or the bridge (tests/conftest.py)

FAULTS_AT = 40.0          # vehicle s: when a cut or a dropped type starts (the runner is armed by 7-20 s)


def _runner(port: int, mission) -> RunnerProcess:
    return RunnerProcess("--target", f"udpout:127.0.0.1:{port}", str(mission), "--heartbeat-timeout", "60",
                         "--rerun", "off")


def _runner_connecting(port: int) -> None:
    """Until the runner, started before the vehicle, sends its first TIMESYNC hello to `port`: its own start (imports,
    warm-up) is behind it, so the vehicle's clock starts with the runner ready and vehicle times are predictable."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", port))
        sock.settimeout(RUN_WAIT)
        sock.recvfrom(65535)


def _fly(tmp_path, faults: str, mission, expect: int, fault_while_flying: bool = False) -> tuple[str, str]:
    """Fly `mission` with `faults` on the runner's link; the run must exit `expect` and leave the vehicle safe.
    Returns (runner output, bridge output)."""
    bridge, checker_port = bridge_with_checker(tmp_path, "--start-depth", "1", "--link-faults", f"{faults},link=0")
    with _runner(bridge.port, mission) as run:
        _runner_connecting(bridge.port)
        with bridge:
            gcs = checker(checker_port)
            try:
                if fault_while_flying:
                    run.wait_for("armed in MANUAL")
                    armed_at = gcs.sim_time_now()
                    assert armed_at < FAULTS_AT - 3.0, f"armed only at {armed_at:.1f} s of vehicle time"
                assert run.wait() == expect, run.output
                assert_left_safe(gcs)
            finally:
                gcs.close()
    return run.output, bridge.output


def test_start_and_a_short_mission_under_30_percent_loss(tmp_path):
    output, bridge_output = _fly(tmp_path, "loss=0.3", short_mission(tmp_path, goto_x=0.4, hold=1.0), expect=0)
    assert "armed in MANUAL" in output and "stopping: mission complete" in output
    counts = re.search(r"link 0 faults: to the vehicle (\d+) sent, (\d+) lost .*; from it (\d+) sent, (\d+) lost",
                       bridge_output)
    up_sent, up_lost, down_sent, down_lost = map(int, counts.groups())
    assert up_sent > 200 and 0.2 < up_lost / up_sent < 0.4            # the loss was there, both ways
    assert down_sent > 2000 and 0.25 < down_lost / down_sent < 0.35


def test_a_cut_longer_than_the_link_timeout_aborts_to_neutral(tmp_path):
    mission = short_mission(tmp_path, goto_x=7.0)                      # 42 s: still flying at FAULTS_AT
    # 7 s: the runner (link timeout 2 s) sees it before it ends even if starved of CPU for 0.5 s of wall time, and
    # the rest of it is over within the 5 wall s the stop keeps sending neutral (at a speedup of 1 or more); the
    # vehicle's own failsafes (pilot input 3 s, GCS 5 s) disarm it meanwhile, as ArduSub's would
    output, _ = _fly(tmp_path, f"cut=7s@{FAULTS_AT:g}s", mission, expect=1, fault_while_flying=True)
    assert "stopping: link lost: no telemetry from the vehicle" in output
    assert "neutral 1500 us on channels 1-8: sent, confirmed by SERVO_OUTPUT_RAW" in output   # once the cut ended
    assert "safe stop NOT complete" not in output


def test_a_restore_never_confirmed_exits_non_zero_naming_the_step(tmp_path):
    mission = short_mission(tmp_path, goto_x=7.0)                      # 42 s: ends after FAULTS_AT
    output, _ = _fly(tmp_path, f"drop=PARAM_VALUE@{FAULTS_AT:g}s", mission, expect=1, fault_while_flying=True)
    assert "stopping: mission complete" in output
    functions = ", ".join(f"SERVO{n}_FUNCTION" for n in range(1, 9))
    assert f"safe stop NOT complete: restore {functions} not confirmed by the vehicle" in output
    assert "NOT restored (no confirmation): SERVO1_FUNCTION=33" in output
