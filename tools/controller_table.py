"""Measure: each controller's shipped gains simulated on the line and the square (the missions' own environments),
printed as the Markdown table of docs/results/controllers.md, and with --figure the page's figure (position and
attitude RMS per controller and mission). Run:
    .venv/bin/python tools/controller_table.py [--figure docs/results/figures/controllers.png]
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from results_figure import save

from rov_mav.control.controller import KINDS, load_settings  # noqa: E402
from rov_mav.mission.metrics import trace_metrics  # noqa: E402
from rov_mav.mission.missions import load_mission  # noqa: E402
from rov_mav.model.vehicle import load_vehicle  # noqa: E402
from rov_mav.offline.simulation import simulate  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
MISSIONS = ("line", "square")


def draw(metrics: dict[tuple[str, str], dict], out: Path) -> None:
    """Position RMS (cm) and attitude RMS (deg), a group of bars per mission, a bar per controller."""
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    width = 0.8 / len(KINDS)
    for ax, (key, scale, label) in zip(axes, (("rms_position_error_m", 100.0, "position error RMS (cm)"),
                                              ("rms_attitude_error_rad", np.degrees(1.0), "attitude error RMS (deg)"))):
        for k, kind in enumerate(KINDS):
            values = [metrics[(mission, kind)][key] * scale for mission in MISSIONS]
            bars = ax.bar(np.arange(len(MISSIONS)) + (k - (len(KINDS) - 1) / 2) * width, values, width, label=kind)
            ax.bar_label(bars, fmt="%.2f", fontsize=7, padding=1, rotation=90)
        ax.set_xticks(np.arange(len(MISSIONS)), MISSIONS)
        ax.set_ylabel(label)
        ax.margins(y=0.2)
        ax.grid(axis="y", alpha=0.3)
    axes[0].legend(fontsize=8, ncols=2)
    fig.suptitle("The shipped gains, simulated on each mission's own environment (state every 10 ms, no delay)",
                 fontsize=11)
    save(fig, out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--figure", type=Path, help="also draw the page's figure (PNG)")
    args = parser.parse_args()
    vehicle = load_vehicle()
    print(f"load average before: {os.getloadavg()[0]:.1f}")
    print("| mission | controller | completed | position RMS (cm) | steady RMS (cm) | max (cm) | attitude RMS (deg) "
          "| effort (N² s) |")
    print("|---|---|---|---:|---:|---:|---:|---:|")
    metrics = {}
    for name in MISSIONS:
        mission = load_mission(ROOT / "missions" / f"{name}.yaml")
        for kind in KINDS:
            m = metrics[(name, kind)] = trace_metrics(name, kind, simulate(mission, load_settings(kind), vehicle))
            print(f"| {name} | {kind} | {'yes' if m['completed'] else 'NO'} | {m['rms_position_error_m'] * 100:.2f} "
                  f"| {m['rms_position_error_steady_m'] * 100:.2f} | {m['max_position_error_m'] * 100:.2f} "
                  f"| {np.degrees(m['rms_attitude_error_rad']):.3f} | {m['control_effort']:.4g} |")
    if args.figure is not None:
        draw(metrics, args.figure)
        print(f"figure: {args.figure}")


if __name__ == "__main__":
    main()
