"""The picture of the default Rerun layout (README, docs/get-started.md): the square simulated, shown in a headless
viewer, captured.

Needs a Vulkan driver (a GPU, or Debian's mesa-vulkan-drivers for software rendering). Run:
    .venv/bin/python tools/rerun_screenshot.py [--time 140] [--out docs/rerun_layout.png]
"""

from __future__ import annotations

import argparse
import socket
import sys
import time
from pathlib import Path

from rerun.experimental import ViewerClient

from rov_mav import telemetry
from rov_mav.control.controller import load_settings
from rov_mav.mission.missions import load_mission
from rov_mav.model.vehicle import load_vehicle
from rov_mav.offline.simulation import simulate

ROOT = Path(__file__).resolve().parents[1]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--time", type=float, default=140.0, help="vehicle time shown, s (default 140)")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "rerun_layout.png")
    args = parser.parse_args()
    mission, vehicle = load_mission(ROOT / "missions" / "square.yaml"), load_vehicle()
    trace = simulate(mission, load_settings("fuzzy"), vehicle)
    viewer = ViewerClient.spawn(headless=True, port=free_port(), hide_welcome_screen=True,
                                executable_path=str(Path(sys.executable).with_name("rerun")))
    try:
        rec = telemetry.open_recording(telemetry.RerunTarget("connect", viewer.url),
                                       telemetry.default_blueprint(trace.reference[:, :3]))
        telemetry.log_trace(rec, trace, vehicle, telemetry.mission_events(mission, trace))
        if not telemetry.finish(rec, timeout=60.0):
            raise SystemExit("the viewer did not take the recording")
        time.sleep(5.0)   # the viewer ingests the run, the start-up notifications fade
        viewer.set_time(telemetry.TIMELINE, duration=args.time, play_state="paused")
        time.sleep(2.0)
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_bytes(viewer.take_screenshot(max_size=1600))
    finally:
        viewer.quit()
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
