"""Measure: each shipped gain set's delay margin on the square, with the state predicted forward and without.

A link d ms late each way leaves the state 2 d + 20 ms old when its command acts (the round trip, a control period
of holding and our processing, as the 50 Hz run measures it: 50 ms each way -> 0.12 s). For every controller and d
it flies the square offline (`simulate`, the same compiled loop and prediction as `rov-mav run`) with the mission's
disturbance, 50 Hz telemetry that old and noisy (robust.yaml's sensor noise), on the nominal plant and on plants 20 %
lighter and heavier than the law's model (the prediction's model is then wrong too), and reports the worst RMS error
of the three; the margin is the largest d at which all three stay within the square's limits (max error 1.5 m,
|roll|, |pitch| 15 deg, no divergence) at every d up to it. Run:
    .venv/bin/python tools/delay_margin.py [--delays 0,25,50,...] [--mission missions/square.yaml]
        [--figure docs/results/figures/delay-margin.png]
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import time
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from results_figure import save

from rov_mav.control.controller import load_settings
from rov_mav.mission.metrics import trace_metrics
from rov_mav.mission.missions import load_mission
from rov_mav.model.vehicle import load_vehicle
from rov_mav.offline.simulation import simulate

ROOT = Path(__file__).resolve().parents[1]
KINDS = ("baseline", "constant", "fuzzy", "pid", "smc", "ismc")
DELAYS_MS = (0, 25, 50, 75, 100, 150, 200, 250, 300, 400)
HOLD = 0.02                 # s: a 50 Hz period of holding and processing on top of the round trip
MAX_TILT = np.radians(15.0)
PLANT_SCALES = (1.0, 0.8, 1.2)
NOISE = np.array([0.02, 0.009, 0.01, 0.005])   # robust.yaml's sensor noise: position, attitude, velocity, rate


def fly(mission, vehicle, kind: str, delay_ms: float, predict: bool) -> tuple[bool, float]:
    """(within the limits on every plant, worst RMS error m) of the square at this delay each way."""
    env = dataclasses.replace(mission.environment, telemetry=np.array([0.02, 2 * delay_ms / 1e3 + HOLD]),
                              noise=NOISE, predict=predict)
    limit = mission.limits.max_tracking_error or np.inf
    within, worst = True, 0.0
    for scale in PLANT_SCALES:
        trace = simulate(mission, load_settings(kind), vehicle, plant=vehicle.scaled(scale), environment=env)
        m = trace_metrics(mission.name, kind, trace)
        within = within and (m["completed"] and m["max_position_error_m"] <= limit
                             and np.abs(trace.eta[:, 3:5]).max() <= MAX_TILT)
        worst = max(worst, m["rms_position_error_m"])
    return within, worst


def draw(curves: dict[tuple[str, bool], list[float]], delays: list[float], out: Path) -> None:
    """The worst RMS against the delay each way, a line per controller, with the prediction (left) and without
    (right); a point left out where a plant left the limits."""
    fig, axes = plt.subplots(1, 2, figsize=(11, 4), sharex=True, sharey=True)
    for ax, predict in zip(axes, (True, False)):
        for kind in KINDS:
            ax.plot(delays, curves[(kind, predict)], "o-", ms=3, label=kind)
        ax.set_title("state predicted forward" if predict else "without the prediction")
        ax.set_xlabel("link delay each way (ms)")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("worst position error RMS (cm)")
    axes[0].legend(fontsize=8)
    axes[1].annotate("a missing point: a plant left the square's limits", (0.25, 0.9), xycoords="axes fraction",
                     fontsize=8, color="grey")
    fig.suptitle("The square through a late link (offline, plants 20 % lighter and heavier than the model)",
                 fontsize=11)
    save(fig, out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mission", type=Path, default=ROOT / "missions" / "square.yaml")
    parser.add_argument("--delays", default=",".join(str(d) for d in DELAYS_MS), help="ms each way, ascending")
    parser.add_argument("--figure", type=Path, help="also draw the results page's figure (PNG)")
    args = parser.parse_args()
    mission, vehicle = load_mission(args.mission), load_vehicle()
    delays = [float(d) for d in args.delays.split(",")]
    start = time.perf_counter()
    print(f"mission {mission.name}; state age 2 x delay + {HOLD * 1e3:.0f} ms, 50 Hz telemetry with noise; plants "
          f"x{', x'.join(f'{s:g}' for s in PLANT_SCALES)}; worst RMS of the plants; load average before: "
          f"{os.getloadavg()[0]:.1f}")
    print("Worst RMS position error (cm) at each delay each way (ms):\n")
    print("| controller | prediction | margin | " + " | ".join(f"{d:g}" for d in delays) + " |")
    print("|---|---|---:|" + "---:|" * len(delays))
    curves: dict[tuple[str, bool], list[float]] = {}
    for kind in KINDS:
        for predict in (True, False):
            cells, margin, holding = [], None, True
            curve = curves[(kind, predict)] = []
            for d in delays:
                within, rms = fly(mission, vehicle, kind, d, predict)
                cells.append(f"{rms * 100:.2f}" if within else "out")
                curve.append(rms * 100 if within else float("nan"))
                holding = holding and within
                margin = d if holding else margin
            shown = "none" if margin is None else f"{margin:g} ms"
            print(f"| {kind} | {'on' if predict else 'off'} | {shown} | " + " | ".join(cells) + " |", flush=True)
    print(f"{time.perf_counter() - start:.0f} s; load average after: {os.getloadavg()[0]:.1f}")
    if args.figure is not None:
        draw(curves, delays, args.figure)
        print(f"figure: {args.figure}")


if __name__ == "__main__":
    main()
