"""The vehicle-faults results page's figure, drawn from `tools/vehicle_faults.py`'s own table (its markdown rows):
per fault, how long the run took to answer it and the tracking error after it, whether the mission was completed or
the run stopped safely. Run:
    .venv/bin/python tools/vehicle_faults_figure.py TABLE.txt --out docs/results/figures/vehicle-faults.png
"""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from results_figure import markdown_rows, number, redraw, save

COMPLETED, STOPPED = "#2ca02c", "#ff7f0e"


def read_rows(text: str) -> list[dict]:
    rows = []
    for row in markdown_rows(text):
        if "what the run said" not in row:
            continue
        rms, _, worst = row["RMS / max error after it"].partition("/")
        rows.append({"fault": row["label"].split(" (")[0], "after": number(row["after (vehicle s)"]),
                     "completed": row["completed / exit"].startswith("yes"), "rms": number(rms),
                     "max": number(worst)})
    return rows


def draw(rows: list[dict], out: Path) -> None:
    y = np.arange(len(rows))[::-1]
    colours = [COMPLETED if r["completed"] else STOPPED for r in rows]
    fig, (answer, error) = plt.subplots(1, 2, figsize=(11, 0.45 * len(rows) + 1.6), sharey=True)
    answer.barh(y, [0.0 if math.isnan(r["after"]) else r["after"] for r in rows], color=colours)
    for k, r in zip(y, rows):
        if math.isnan(r["after"]):
            answer.text(0.1, k, "on the vehicle's first message after the boot" if "reboot" in r["fault"] else "-",
                        va="center", fontsize=8)
    answer.set_yticks(y, [r["fault"] for r in rows], fontsize=8)
    answer.set_xlabel("from the fault to the run's answer (vehicle s)")
    error.barh(y, [r["rms"] for r in rows], color=colours)
    error.plot([r["max"] for r in rows], y, "|", color="k", markersize=12)
    error.set_xscale("log")
    error.set_xlabel("position error after the fault (cm, log scale)")
    for ax in (answer, error):
        ax.grid(axis="x", alpha=0.3)
    error.legend(handles=[plt.Rectangle((0, 0), 1, 1, color=COMPLETED), plt.Rectangle((0, 0), 1, 1, color=STOPPED),
                          plt.Line2D([], [], marker="|", color="k", linestyle="none", markersize=12)],
                 labels=["mission completed", "run stopped safely", "max"], fontsize=8, loc="lower right")
    fig.suptitle("Each fault on the built-in vehicle, the square at 5x, the fault at mission t = 60 s", fontsize=11)
    save(fig, out)


if __name__ == "__main__":
    redraw(__doc__.splitlines()[0], "tools/vehicle_faults.py", read_rows, draw)
