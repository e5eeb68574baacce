"""Reproduce the report's experiments: the counterparts of Figs. IV-2 to IV-8 and a comparison table.

Runs baseline, constant-rate and fuzzy-rate adaptation on the line (Eq. 3.1, tau_d of Eq. 3.2) and on the square,
each with the controller's model equal to the plant and 20 % off it (plant mass, inertia, added mass and damping
x1.2 — docs/errata.md, "What adaptation buys"). Writes PNG figures and `table.md` to the output folder (default
docs/report). Run:  .venv/bin/python tools/reproduce_report.py [--out DIR]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from rov_mav.control.controller import REPORT_GAINS, load_settings
from rov_mav.mission.metrics import trace_metrics
from rov_mav.mission.missions import load_mission
from rov_mav.model.vehicle import load_vehicle
from rov_mav.offline.plots import plot_dofs, plot_estimates, plot_path
from rov_mav.offline.simulation import simulate

ROOT = Path(__file__).resolve().parents[1]
CONTROLLERS = ("baseline", "constant", "fuzzy")
PLANT_ERRORS = {"matched": 1.0, "plant +20 %": 1.2}


def run_all():
    model = load_vehicle()
    traces, rows = {}, []
    for mission_name in ("line", "square"):
        mission = load_mission(ROOT / "missions" / f"{mission_name}.yaml")
        for error_name, factor in PLANT_ERRORS.items():
            plant = model.scaled(factor)
            for kind in CONTROLLERS:
                trace = simulate(mission, load_settings(kind, REPORT_GAINS), model, plant)
                traces[(mission_name, error_name, kind)] = trace
                m = trace_metrics(mission_name, kind, trace)
                estimate_error = np.abs(np.array(m["final_disturbance_estimate"]) - mission.environment.disturbance)
                rows.append((mission_name, error_name, kind, m, estimate_error))
    return traces, rows


def table(rows) -> str:
    head = ("| mission | model | controller | RMS pos (cm) | steady pos (cm) | max pos (cm) | RMS att (deg) "
            "| steady att (deg) | final estimate error X, Y, Z (N); K, M, N (N m) | effort ∫τᵀτ dt |")
    lines = [head, "|" + "---|" * 10]
    for mission, error, kind, m, est in rows:
        lines.append(
            f"| {mission} | {error} | {kind} | {m['rms_position_error_m'] * 100:.2f} "
            f"| {m['rms_position_error_steady_m'] * 100:.2f} | {m['max_position_error_m'] * 100:.2f} "
            f"| {np.degrees(m['rms_attitude_error_rad']):.2f} | {np.degrees(m['rms_attitude_error_steady_rad']):.3f} "
            f"| {est[0]:.2f}, {est[1]:.2f}, {est[2]:.2f}; {est[3]:.3f}, {est[4]:.3f}, {est[5]:.3f} "
            f"| {m['control_effort']:,.0f} |")
    return "\n".join(lines) + "\n"


def figures(traces, out: Path) -> list[Path]:
    line = {k: traces[("line", "matched", k)] for k in CONTROLLERS}
    square = traces[("square", "matched", "fuzzy")]
    return [
        plot_dofs(line["baseline"], "Fig. IV-2: baseline backstepping on the line", out / "fig_iv2_line_baseline.png"),
        plot_dofs(line["fuzzy"], "Fig. IV-3: fuzzy adaptive on the line", out / "fig_iv3_line_fuzzy.png"),
        plot_path({"baseline": line["baseline"], "fuzzy": line["fuzzy"]}, "Fig. IV-4: line, 3D",
                  out / "fig_iv4_line_3d.png"),
        plot_estimates(line["constant"], "Fig. IV-5: constant-rate estimates (line)",
                       out / "fig_iv5_estimates_constant.png"),
        plot_estimates(line["fuzzy"], "Fig. IV-6: fuzzy-rate estimates (line)", out / "fig_iv6_estimates_fuzzy.png"),
        plot_path({"fuzzy": square}, "Fig. IV-7: square, 3D", out / "fig_iv7_square_3d.png"),
        plot_estimates(square, "Fig. IV-8: estimates on the square", out / "fig_iv8_square_estimates.png"),
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(ROOT / "docs" / "report"), help="output folder (default docs/report)")
    out = Path(parser.parse_args().out)
    out.mkdir(parents=True, exist_ok=True)
    traces, rows = run_all()
    text = table(rows)
    (out / "table.md").write_text(text)
    print(text)
    for path in figures(traces, out):
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
