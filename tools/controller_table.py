"""Measure: each controller's shipped gains simulated on the line and the square (the missions' own environments),
printed as the Markdown table of docs/results/controllers.md. Run:
    .venv/bin/python tools/controller_table.py
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rov_mav.control.controller import KINDS, load_settings
from rov_mav.mission.metrics import trace_metrics
from rov_mav.mission.missions import load_mission
from rov_mav.model.vehicle import load_vehicle
from rov_mav.offline.simulation import simulate

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    vehicle = load_vehicle()
    print("| mission | controller | completed | position RMS (cm) | steady RMS (cm) | max (cm) | attitude RMS (deg) "
          "| effort (N² s) |")
    print("|---|---|---|---:|---:|---:|---:|---:|")
    for name in ("line", "square"):
        mission = load_mission(ROOT / "missions" / f"{name}.yaml")
        for kind in KINDS:
            m = trace_metrics(name, kind, simulate(mission, load_settings(kind), vehicle))
            print(f"| {name} | {kind} | {'yes' if m['completed'] else 'NO'} | {m['rms_position_error_m'] * 100:.2f} "
                  f"| {m['rms_position_error_steady_m'] * 100:.2f} | {m['max_position_error_m'] * 100:.2f} "
                  f"| {np.degrees(m['rms_attitude_error_rad']):.3f} | {m['control_effort']:.4g} |")


if __name__ == "__main__":
    main()
