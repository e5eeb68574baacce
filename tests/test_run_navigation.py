"""A run on navigation as a dive has it, end to end: the built-in vehicle's acoustic positioning (`navigation: ugps`
in the mission's environment) with its own estimator, and the run's figures against the truth it also sends
(SIM_STATE), read back the same by `analyze`; on the ideal navigation (no SIM_STATE) nothing is claimed about a
truth."""

from __future__ import annotations

import json
import math
import subprocess
from pathlib import Path

import pytest

from run_helpers import ROV_MAV, RunnerProcess

pytestmark = pytest.mark.process      # starts a process or the bridge (tests/conftest.py)

MISSION = """name: navtest
start: {position: [0.0, 0.0, 1.0], heading: 0.0}
path:
  - {goto: [3.0, 0.0, 1.0], speed: 0.2}
environment:
  disturbance: [-1.0, 1.0, 2.0, 0.1, 0.1, 0.0]
  navigation: NAVIGATION
"""
SQUARE = MISSION.replace("  - {goto: [3.0, 0.0, 1.0], speed: 0.2}",
                         "  - {goto: [4.0, 0.0, 1.0], speed: 0.25}\n  - {goto: [4.0, 3.0, 1.0], speed: 0.25}\n"
                         "  - {goto: [0.0, 3.0, 1.0], speed: 0.25}\n  - {goto: [0.0, 0.0, 1.0], speed: 0.25}")


def _fly(tmp_path, mission_text: str, *args: str) -> tuple[int, str, dict, Path]:
    """The run's exit status, output, metrics and log of `mission_text` at --speedup 5."""
    mission = tmp_path / "m.yaml"
    mission.write_text(mission_text)
    metrics, log = tmp_path / "metrics.json", tmp_path / "log"
    with RunnerProcess(str(mission), "--speedup", "5", "--metrics", str(metrics), "--log", str(log), *args) as run:
        code = run.wait()
    return code, run.output, json.loads(metrics.read_text()), log


def _analyze(tmp_path, log: Path) -> dict:
    """`analyze`'s metrics of a run's log."""
    analyzed = tmp_path / "analyzed.json"
    subprocess.run([ROV_MAV, "analyze", str(log), "--metrics", str(analyzed), "--rerun", "off", "--out",
                    str(tmp_path / "review")], check=True, capture_output=True, timeout=300)
    return json.loads(analyzed.read_text())


@pytest.fixture(scope="module")
def square_on_the_vehicle_estimate(tmp_path_factory):
    """The square on acoustic fixes flown on the vehicle's own estimate (the default `--estimator vehicle`)."""
    return _fly(tmp_path_factory.mktemp("vehicle_estimate"), SQUARE.replace("NAVIGATION", "ugps"))


def test_on_acoustic_positioning_the_error_is_measured_against_the_truth_beside_the_estimate(
        tmp_path, square_on_the_vehicle_estimate):
    code, output, ran, log = square_on_the_vehicle_estimate
    assert code == 0, output
    truth, estimate = ran["rms_position_error_truth_m"], ran["rms_position_error_m"]
    assert math.isfinite(truth) and ran["truth_samples"] > 100
    assert truth > estimate          # flying the estimate well is not flying the vehicle well: the fixes' error stays
    assert math.isclose(_analyze(tmp_path, log)["rms_position_error_truth_m"], truth, rel_tol=1e-6)
    assert "against the truth (SIM_STATE)" in output
    assert ran["loop"]["pwm_activity_us_per_s"] > 0


def test_on_its_own_estimate_the_run_is_nearer_the_truth_than_on_the_vehicle_estimate(
        tmp_path, square_on_the_vehicle_estimate):
    """`--estimator model` on acoustic fixes: the run's own model-aided estimate (`flight.state.model_estimator`), fed
    by the UGPS driver's GPS_INPUT on the link, is nearer the truth than the vehicle's EKF over the same run, and the
    run flying on it is nearer the truth than the same square flown on the vehicle's estimate (the module's fixture,
    which the test before it shares: the two are side by side so that one worker flies it once)."""
    code, output, ran, _ = _fly(tmp_path, SQUARE.replace("NAVIGATION", "ugps"), "--estimator", "model")
    assert code == 0, output
    ours, vehicle = ran["rms_estimate_error_truth_m"], ran["rms_vehicle_estimate_error_truth_m"]
    assert ours < vehicle, (ours, vehicle)
    flown_on_vehicle = square_on_the_vehicle_estimate[2]["rms_position_error_truth_m"]
    print(f"against the truth: on our estimate {ran['rms_position_error_truth_m']:.4f} m, on the vehicle's "
          f"{flown_on_vehicle:.4f} m; estimators {ours:.4f} m (ours), {vehicle:.4f} m (vehicle)")
    assert ran["rms_position_error_truth_m"] < flown_on_vehicle
    assert "flying on the run's own estimate from here: an acoustic fix (GPS_INPUT) started it" in output


def test_on_the_ideal_navigation_nothing_is_claimed_about_a_truth(tmp_path):
    code, output, ran, log = _fly(tmp_path, MISSION.replace("NAVIGATION", "ideal"))
    assert code == 0, output
    analyzed = _analyze(tmp_path, log)
    assert "rms_position_error_truth_m" not in ran and "rms_position_error_truth_m" not in analyzed
    assert "against the truth" not in output


def test_without_a_position_source_the_run_refuses_in_one_line_and_touches_nothing(tmp_path):
    """`--navigation none`, as most BlueROV2s: attitude and depth only, never a LOCAL_POSITION_NED."""
    mission = tmp_path / "m.yaml"
    mission.write_text(MISSION.replace("NAVIGATION", "ideal"))
    with RunnerProcess(str(mission), "--navigation", "none", "--position-timeout", "5", "--speedup", "5") as run:
        code = run.wait()
    assert code == 1, run.output
    assert "no LOCAL_POSITION_NED from the vehicle after 5 s: the vehicle's estimator has no position source" \
        in run.output
    assert "armed in" not in run.output and "set to RCIN" not in run.output
    with RunnerProcess("--target", "udp:127.0.0.1:9", str(mission), "--navigation", "ugps") as run:
        assert run.wait() == 2 and "--navigation applies to the built-in vehicle only" in run.output


def test_ardusubs_guided_cannot_fly_on_the_runs_own_estimate(tmp_path):
    mission = tmp_path / "m.yaml"
    mission.write_text(MISSION.replace("NAVIGATION", "ugps"))
    with RunnerProcess(str(mission), "--controller", "ardusub-guided", "--estimator", "model") as run:
        assert run.wait() == 2
    assert "--estimator model is the law's; --controller ardusub-guided flies on ArduSub's own estimate" in run.output
    assert len(run.output.strip().splitlines()) == 1
