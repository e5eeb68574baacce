"""The autotune results page's figure, drawn from `tools/autotune_table.py`'s own table (its markdown rows): per
vehicle, the square's RMS position error with the shipped model and gains and with what autotune kept, and their
ratio against the 0.6 goal. Run:
    .venv/bin/python tools/autotune_figure.py TABLE.txt --out docs/results/figures/autotune.png
"""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from results_figure import markdown_rows, number, redraw, save

BEFORE, AFTER = "square, shipped: RMS / max (cm)", "autotuned: RMS / max (cm)"
GOAL = 0.6


def read_rows(text: str) -> list[dict]:
    return [{"vehicle": row["label"], "before": number(row[BEFORE]), "after": number(row[AFTER]),
             "ratio": number(row["ratio"]), "outcome": row["autotune"]} for row in markdown_rows(text) if BEFORE in row]


def draw(rows: list[dict], out: Path) -> None:
    x = np.arange(len(rows))
    fig, ax = plt.subplots(figsize=(7, 3.8))
    ax.bar(x - 0.2, [r["before"] for r in rows], 0.4, color="#7f7f7f", label="shipped model and gains")
    ax.bar(x + 0.2, [r["after"] for r in rows], 0.4, color="#1f77b4", label="after rov-mav autotune")
    for xi, r in zip(x, rows):
        shown = f"{r['ratio']:.2f}x" if np.isfinite(r["after"]) else r["outcome"].replace(" (", "\n(")
        ax.annotate(shown, (xi + 0.2, r["after"] if np.isfinite(r["after"]) else 0.0), textcoords="offset points",
                    xytext=(0, 3), ha="center", fontsize=8)
    ax.hlines([GOAL * r["before"] for r in rows], x - 0.4, x + 0.4, colors="k", linestyles="--", linewidth=0.8,
              label=f"the {GOAL}x goal")
    ax.set_xticks(x, [r["vehicle"] for r in rows])
    ax.set_ylabel("the square: RMS position error (cm)")
    ax.legend(fontsize=8)
    ax.grid(axis="y", alpha=0.3)
    ax.set_title("Three vehicles unlike the model, on the built-in vehicle", fontsize=11)
    save(fig, out)


if __name__ == "__main__":
    redraw(__doc__.splitlines()[0], "tools/autotune_table.py", read_rows, draw)
