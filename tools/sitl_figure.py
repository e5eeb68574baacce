"""The SITL results page's figure, drawn from `tools/sitl_square.py`'s tables (their markdown rows, as the page
keeps them): per model the law flew, the square's error against SITL's EKF (what the controller sees) and against
SITL's true pose, and the EKF's own horizontal error against the truth (the floor no controller fed by it removes).
Run:
    .venv/bin/python tools/sitl_figure.py TABLE.txt [TABLE.txt ...] --out docs/results/figures/sitl.png
"""

from __future__ import annotations

import textwrap
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from results_figure import markdown_rows, number, redraw, save

FLOOR = "EKF − truth: horiz. RMS cm / vert. offset, RMS cm / heading RMS °"


def read_rows(text: str) -> list[dict]:
    """The rows with a truth column; the EKF floor from the page's merged column or the tool's own."""
    rows = []
    for row in markdown_rows(text):
        if "truth RMS 3D cm" not in row:
            continue
        floor = row.get(FLOOR, row.get("EKF-truth horiz cm", "nan"))
        rows.append({"label": row["label"].replace("**", ""), "rms": number(row["RMS 3D cm"]),
                     "max": number(row["max 3D cm"]), "truth": number(row["truth RMS 3D cm"]),
                     "floor": number(floor)})
    return rows


def draw(rows: list[dict], out: Path) -> None:
    y = np.arange(len(rows))[::-1]
    fig, ax = plt.subplots(figsize=(11, 0.55 * len(rows) + 2.2))
    ax.barh(y + 0.2, [r["rms"] for r in rows], 0.4, color="#1f77b4", label="RMS against the EKF (what the law sees)")
    ax.barh(y - 0.2, [r["truth"] for r in rows], 0.4, color="#aec7e8", label="RMS against SITL's true pose")
    ax.plot([r["max"] for r in rows], y + 0.2, "|", color="k", markersize=11, label="max against the EKF")
    ax.plot([r["floor"] for r in rows], y - 0.2, "x", color="#d62728", label="the EKF's own horizontal error (floor)")
    ax.set_yticks(y, ["\n".join(textwrap.wrap(r["label"], 48)) for r in rows], fontsize=7.5)
    ax.set_xscale("log")
    ax.set_xlabel("3D position error on the square (cm, log scale)")
    ax.grid(axis="x", alpha=0.3)
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.4, -0.09), ncol=2)
    ax.set_title("The square on ArduSub SITL, per model the law flies (means of two runs unless marked)", fontsize=11)
    save(fig, out)


if __name__ == "__main__":
    redraw(__doc__.splitlines()[0], "tools/sitl_square.py", read_rows, draw)
