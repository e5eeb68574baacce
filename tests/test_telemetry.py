"""Rerun telemetry: recordings read back, the live sink's batching, dropping and survival, the --rerun option."""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import MISSIONS, ROOT
from telemetry_helpers import (
    free_port,
    read_column,
    temporal_entities,
    tick_records,
    wait_listening,
)

from rov_mav import telemetry
from rov_mav.commands.common import rerun_recording
from rov_mav.control.controller import load_settings
from rov_mav.mission.metrics import run_metrics
from rov_mav.mission.missions import load_mission
from rov_mav.model import dynamics
from rov_mav.model.thrusters import Allocator
from rov_mav.offline.simulation import simulate
from rov_mav.telemetry import entities as e

pytestmark = pytest.mark.process      # starts a process or the bridge (tests/conftest.py)

SIMULATED = {e.VEHICLE, e.TRAIL, e.REFERENCE_NOW, e.ARROWS, *e.POSE, e.POSITION_ERROR, e.ATTITUDE_ERROR, e.SLIDING,
             e.FORCE, e.MOMENT, e.DISTURBANCE_FORCE, e.DISTURBANCE_MOMENT, e.GAMMA_TRANSLATION, e.GAMMA_ROTATION,
             e.THRUST, e.PWM, e.EVENTS}
LIVE_ONLY = {e.LINK, e.BATTERY, e.PROGRESS}


@pytest.fixture(autouse=True)
def no_analytics(tmp_path_factory, monkeypatch):
    """Rerun's config (analytics off) in a temporary folder, for this process and the viewers it starts."""
    config = tmp_path_factory.getbasetemp() / "xdg"
    if not (config / "rerun").exists():
        config.mkdir(exist_ok=True)
        subprocess.run([str(Path(sys.executable).with_name("rerun")), "analytics", "disable"], check=True,
                       env={**os.environ, "XDG_CONFIG_HOME": str(config)}, capture_output=True, timeout=60)
    monkeypatch.setenv("XDG_CONFIG_HOME", str(config))


@pytest.fixture(scope="module")
def square(vehicle):
    """The first 12 s of the square (it turns no corner, but every signal moves)."""
    mission = load_mission(MISSIONS / "square.yaml")
    return mission, simulate(mission, load_settings("fuzzy"), vehicle, duration=12.0)


def save(path: Path, reference_path=None):
    return telemetry.open_recording(telemetry.RerunTarget("save", str(path)),
                                    telemetry.default_blueprint(reference_path))


def test_recorded_run_has_every_tick_and_the_runs_metrics(tmp_path, vehicle, square):
    mission, trace = square
    rrd = tmp_path / "run.rrd"
    rec = save(rrd, trace.reference[:, :3])
    telemetry.log_trace(rec, trace, vehicle, telemetry.mission_events(mission, trace))
    assert telemetry.finish(rec)
    n = len(trace.t)

    assert temporal_entities(rrd) == {"/" + p for p in SIMULATED}
    t, translation = read_column(rrd, e.VEHICLE, "Transform3D:translation")
    np.testing.assert_allclose(t, trace.t, atol=1e-9)
    np.testing.assert_allclose(translation[-1][0], trace.eta[-1, :3], atol=1e-9)
    _, rotation = read_column(rrd, e.VEHICLE, "Transform3D:mat3x3")
    np.testing.assert_allclose(np.reshape(rotation[-1][0], (3, 3)).T, dynamics.rotation(trace.eta[-1]), atol=1e-6)

    metrics = run_metrics(mission.name, "fuzzy", trace.t, trace.eta, trace.reference[:, :6], trace.tau,
                          trace.tau_hat, trace.true_disturbance, trace.completed)
    _, errors = read_column(rrd, e.POSITION_ERROR, "Scalars:scalars")
    norm = np.array(errors)[:, 3]
    assert len(norm) == n
    assert np.sqrt(np.mean(norm**2)) == pytest.approx(metrics["rms_position_error_m"], rel=1e-9)
    assert norm.max() == pytest.approx(metrics["max_position_error_m"], rel=1e-9)
    _, force = read_column(rrd, e.DISTURBANCE_FORCE, "Scalars:scalars")
    _, moment = read_column(rrd, e.DISTURBANCE_MOMENT, "Scalars:scalars")
    np.testing.assert_allclose(force[-1][:3] + moment[-1][:3], metrics["final_disturbance_estimate"], atol=1e-9)
    np.testing.assert_allclose(force[-1][3:] + moment[-1][3:], metrics["true_disturbance"], atol=1e-9)

    _, thrusts = read_column(rrd, e.THRUST, "Scalars:scalars")
    wrench = Allocator.for_vehicle(vehicle, 16.0).wrench(np.array(thrusts))
    np.testing.assert_allclose(wrench, trace.tau, atol=1e-6)      # the arrows add up to the commanded tau
    _, arrows = read_column(rrd, e.ARROWS, "Arrows3D:vectors")
    np.testing.assert_allclose(arrows[-1], e.ARROW_SCALE * np.array(thrusts[-1])[:, None]
                               * vehicle.thruster_directions, atol=1e-6)

    t_events, text = read_column(rrd, e.EVENTS, "TextLog:text")
    assert text[0][0].startswith("path[0]: goto [10.0, 0.0, 1.0]") and t_events[0] == 0.0
    assert text[-1] == ["run completed"] and t_events[-1] == pytest.approx(trace.t[-1])


def test_every_tick_entity_has_one_row_per_tick(tmp_path, vehicle, square):
    _, trace = square
    rrd = tmp_path / "run.rrd"
    rec = save(rrd)
    telemetry.log_trace(rec, trace, vehicle)
    telemetry.finish(rec)
    components = {e.VEHICLE: "Transform3D:translation", e.TRAIL: "LineStrips3D:strips",
                  e.REFERENCE_NOW: "Points3D:positions", e.ARROWS: "Arrows3D:vectors"}
    for path in SIMULATED - {e.EVENTS}:
        t, _ = read_column(rrd, path, components.get(path, "Scalars:scalars"))
        np.testing.assert_allclose(t, trace.t, atol=1e-9, err_msg=path)


def test_live_sink_logs_every_tick_with_a_continuous_trail(tmp_path, vehicle, square):
    _, trace = square
    records = tick_records(trace, vehicle, t0=-1.0)    # the runner's lead-in runs at negative mission time
    rrd = tmp_path / "live.rrd"
    sink = telemetry.RerunSink(save(rrd), vehicle, trace.reference[:, :3], period=0.01, capacity=len(records))
    for k, record in enumerate(records):
        sink.log_tick(record)
        if k % 100 == 0:
            sink.log_event(record.t, f"tick {k}", "warning")
            time.sleep(0.02)                           # several batches
    sink.close()
    stats = sink.stats
    assert (stats.ticks, stats.logged, stats.dropped, stats.errors) == (len(records), len(records), 0, 0)

    assert temporal_entities(rrd) == {"/" + p for p in SIMULATED | LIVE_ONLY}
    t, strips = read_column(rrd, e.TRAIL, "LineStrips3D:strips")
    np.testing.assert_allclose(t, [r.t for r in records], atol=1e-9)
    strips = np.array(strips)[:, 0]                    # (n, 2, 3): segment k runs from position k-1 to k
    np.testing.assert_allclose(strips[1:, 0], strips[:-1, 1], atol=1e-12)
    np.testing.assert_allclose(strips[:, 1], trace.eta[:, :3], atol=1e-12)
    _, link = read_column(rrd, e.LINK, "Scalars:scalars")
    np.testing.assert_allclose(np.array(link)[-1], [1e3 * records[-1].telemetry_age, 50.0])
    _, battery = read_column(rrd, e.BATTERY, "Scalars:scalars")
    assert battery[-1] == [pytest.approx(records[-1].battery_voltage)]
    _, levels = read_column(rrd, e.EVENTS, "TextLog:level")
    assert {row[0] for row in levels} == {"WARN"}


def test_live_sink_drops_ticks_instead_of_waiting_when_behind(tmp_path, vehicle, square):
    _, trace = square
    records = tick_records(trace, vehicle)[:50]
    sink = telemetry.RerunSink(save(tmp_path / "live.rrd"), vehicle, period=60.0, capacity=10)
    for record in records:                             # the thread sleeps for 60 s: nothing is drained
        sink.log_tick(record)
    assert sink.stats.dropped == 40
    sink.close()                                       # logs the 10 it kept
    assert (sink.stats.logged, sink.stats.dropped) == (10, 40)


def test_live_sink_survives_the_viewer_going_away(vehicle, square):
    _, trace = square
    records = tick_records(trace, vehicle)
    port = free_port()
    server = subprocess.Popen([str(Path(sys.executable).with_name("rerun")), "--serve-grpc", "--port", str(port)],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        wait_listening(port, 30.0)
        rec = telemetry.open_recording(telemetry.RerunTarget("connect", f"rerun+http://127.0.0.1:{port}/proxy"),
                                       telemetry.default_blueprint())
        sink = telemetry.RerunSink(rec, vehicle, period=0.02, capacity=len(records), close_timeout=1.0)
        half = len(records) // 2
        for record in records[:half]:
            sink.log_tick(record)
        time.sleep(0.2)
    finally:   # the `rerun` script runs the viewer binary as a child: end the whole process group
        os.killpg(server.pid, signal.SIGKILL)
        server.wait(timeout=30)
    for record in records[half:]:                      # the viewer is gone: the loop goes on
        sink.log_tick(record)
    time.sleep(0.2)
    start = time.monotonic()
    sink.close()
    assert time.monotonic() - start < 20.0
    stats = sink.stats
    assert (stats.ticks, stats.logged, stats.dropped, stats.errors) == (len(records), len(records), 0, 0)
    assert stats.call_per_tick < 1e-3


@pytest.mark.parametrize("text, mode, location", [
    ("spawn", "spawn", None), ("off", "off", None), ("connect", "connect", telemetry.target.DEFAULT_URL),
    ("connect:rerun+http://10.0.0.2:9876/proxy", "connect", "rerun+http://10.0.0.2:9876/proxy"),
    ("save:out/x.rrd", "save", "out/x.rrd")])
def test_rerun_option_forms(text, mode, location):
    assert telemetry.parse_target(text) == telemetry.RerunTarget(mode, location)


@pytest.mark.parametrize("text", ["save", "save:", "spawn:now", "file:x.rrd", ""])
def test_rerun_option_errors(text):
    with pytest.raises(ValueError):
        telemetry.parse_target(text)


def test_default_is_a_viewer_with_a_display_and_a_file_without():
    assert telemetry.default_target("a.rrd", {"DISPLAY": ":0"}).mode == "spawn"
    assert telemetry.default_target("a.rrd", {"WAYLAND_DISPLAY": "wayland-0"}).mode == "spawn"
    assert telemetry.default_target("a.rrd", {}) == telemetry.RerunTarget("save", "a.rrd")


def test_without_a_viewer_to_connect_to_the_telemetry_is_saved(tmp_path, capsys):
    url = f"rerun+http://127.0.0.1:{free_port()}/proxy"
    args = argparse.Namespace(rerun=telemetry.RerunTarget("connect", url))
    target, rec = rerun_recording(args, tmp_path / "run.rrd")
    assert target == telemetry.RerunTarget("save", str(tmp_path / "run.rrd"))
    assert f"no Rerun viewer at {url}" in capsys.readouterr().err
    assert telemetry.finish(rec) and (tmp_path / "run.rrd").stat().st_size > 0


def test_simulate_without_a_display_saves_a_recording_and_says_how_to_open_it(tmp_path):
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    out = tmp_path / "out"
    result = subprocess.run([sys.executable, "-m", "rov_mav.cli", "simulate", str(MISSIONS / "line.yaml"),
                             "--duration", "2", "--out", str(out)], cwd=ROOT, env=env, capture_output=True,
                            text=True, timeout=180)
    assert result.returncode == 0, result.stderr
    rrd = out / "run.rrd"
    assert f"rerun {rrd}" in result.stdout
    t, _ = read_column(rrd, e.VEHICLE, "Transform3D:translation")
    assert len(t) == 201
