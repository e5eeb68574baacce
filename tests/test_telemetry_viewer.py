"""The live stream as a person sees it: a headless Rerun viewer (software Vulkan) fed by the runner's sink.

Needs a Vulkan driver: Debian's mesa-vulkan-drivers (.ci/run installs it). The screenshot is left in
out/test-artifacts/rerun_live.png.
"""

from __future__ import annotations

import glob
import io
import subprocess
import sys
import time
from pathlib import Path

import matplotlib.image
import numpy as np
import pytest
from conftest import MISSIONS, ROOT
from rerun.experimental import ViewerClient
from telemetry_helpers import free_port, tick_records

from rov_mav import telemetry
from rov_mav.control.controller import load_settings
from rov_mav.mission.missions import load_mission
from rov_mav.offline.simulation import simulate
from rov_mav.telemetry import entities as e

ARTIFACT = ROOT / "out" / "test-artifacts" / "rerun_live.png"
VULKAN_DRIVERS = glob.glob("/usr/share/vulkan/icd.d/*.json") + glob.glob("/etc/vulkan/icd.d/*.json")

pytestmark = [pytest.mark.process, pytest.mark.skipif(
    not VULKAN_DRIVERS, reason="no Vulkan driver for the headless viewer: apt-get install mesa-vulkan-drivers")]


@pytest.fixture
def viewer(tmp_path, monkeypatch):
    """A headless viewer on a free port, with analytics off, stopped after the test."""
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path))
    rerun = str(Path(sys.executable).with_name("rerun"))
    subprocess.run([rerun, "analytics", "disable"], check=True, capture_output=True, timeout=60)
    client = ViewerClient.spawn(headless=True, port=free_port(), hide_welcome_screen=True, executable_path=rerun)
    try:
        yield client
    finally:
        client.quit(timeout=10.0)


def wait_for(condition, timeout: float, what: str):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = condition()
        if value:
            return value
        time.sleep(0.25)
    raise TimeoutError(f"{what} within {timeout} s")


def colour_fraction(png: bytes, rgb: tuple[int, ...], tolerance: float = 0.1) -> float:
    """Fraction of the image's pixels of the hue of `rgb`: the same colour, scaled in brightness by blending on the
    dark background, within `tolerance` of the unit RGB direction."""
    image = matplotlib.image.imread(io.BytesIO(png), format="png")[..., :3].astype(float)
    target = np.array(rgb[:3], dtype=float) / np.linalg.norm(rgb[:3])
    norm = np.linalg.norm(image, axis=-1)
    bright = norm > 0.15
    return float(np.mean(bright & (np.linalg.norm(image / np.maximum(norm, 1e-9)[..., None] - target, axis=-1)
                                   < tolerance)))


def test_headless_viewer_shows_the_live_run(viewer, vehicle):
    mission = load_mission(MISSIONS / "square.yaml")
    trace = simulate(mission, load_settings("fuzzy"), vehicle, duration=12.0)
    records = tick_records(trace, vehicle)
    rec = telemetry.open_recording(telemetry.RerunTarget("connect", viewer.url),
                                   telemetry.default_blueprint(trace.reference[:, :3]))
    sink = telemetry.RerunSink(rec, vehicle, trace.reference[:, :3], period=0.05, capacity=len(records))
    sink.log_event(0.0, "armed in MANUAL", "info")
    for record in records:                 # 12 s of 100 Hz ticks at about 10x real time
        sink.log_tick(record)
        time.sleep(0.001)
    sink.log_event(records[-1].t, "mission complete", "info")
    sink.close()
    assert (sink.stats.logged, sink.stats.errors) == (len(records), 0)

    end = records[-1].t * 1e9                  # ns
    state = wait_for(lambda: (s := viewer.get_state()).recordings and s.views
                     and abs(s.recordings[0].timelines[0].end - end) < 1e3 and s,
                     60.0, "the viewer did not receive the whole run")
    assert [t.name for t in state.recordings[0].timelines] == [e.TIMELINE]
    names = {v.name: v for v in state.views}
    assert len(names) == 22
    assert {"Vehicle (NED)", "Events", "Position error (m)", "Attitude error (deg)", "Thrust (N)", "PWM (us)",
            "Link", "Battery (V)", "yaw (deg)"} <= set(names)
    assert [(v.name, r.summary) for v in state.views for r in v.reports] == []

    schema = viewer.get_recording_schema(max_entities=100)
    components = {s.entity_path: s.components for s in schema.entities}
    for path in (e.VEHICLE, e.HULL, e.ARROWS, e.TRAIL, e.REFERENCE_PATH, e.REFERENCE_NOW, *e.POSE,
                 e.POSITION_ERROR, e.DISTURBANCE_FORCE, e.THRUST, e.PWM, e.LINK, e.BATTERY, e.EVENTS):
        assert components.get("/" + path), f"{path} has no data in the viewer"

    scene = viewer.take_screenshot(names["Vehicle (NED)"].view_id)
    assert colour_fraction(scene, e.HULL_COLOR) > 1e-4, "the hull is not drawn"
    assert colour_fraction(scene, e.TRAIL_COLOR) > 1e-4, "the trail is not drawn"
    errors = viewer.take_screenshot(names["Position error (m)"].view_id)
    for colour in (e.RED, e.GREEN, e.BLUE):
        assert colour_fraction(errors, colour) > 1e-4, f"no {colour} series in the position error plot"

    ARTIFACT.parent.mkdir(parents=True, exist_ok=True)
    viewer.save_screenshot(str(ARTIFACT))
    assert ARTIFACT.stat().st_size > 10_000
