"""The transects' figure for the manual's results page, drawn from `tools/transect_table.py`'s own table (its
markdown rows, as it printed them): the height held above the true bottom (RMS, cm) per bottom and controller, on
DVL navigation with the Ping-like sounder, without a current and in 0.2 m/s across the line. Run:
    .venv/bin/python tools/transect_figure.py TABLE.txt [TABLE.txt ...] --out docs/results/transects.png
(`tools/transect_table.py --figure PNG` draws it at the end of a measurement.)
"""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from results_figure import redraw, save

CONTROLLERS = ("fuzzy", "ismc", "ardusub-guided", "surftrak")
LABELS = {"fuzzy": "rov-mav fuzzy", "ismc": "rov-mav ismc", "ardusub-guided": "ArduSub GUIDED ABOVE_TERRAIN",
          "surftrak": "ArduSub SURFTRAK + pilot"}
COLOURS = {"fuzzy": "#1f77b4", "ismc": "#6baed6", "ardusub-guided": "#d62728", "surftrak": "#ff9896"}
TICKS = {"ice": "ice\n(1.5 m below)", "real": "real dive's\nbottom"}
GOAL = 5.0                       # cm: the real bottom's goal


def read_rows(text: str) -> list[dict]:
    """The table's data rows (bottom, current, sounder, navigation, controller, then the figures) as dicts."""
    rows = []
    for line in text.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) < 8 or cells[0] in ("bottom", "---") or set(cells[0]) <= {"-"}:
            continue
        rows.append({"bottom": cells[0], "current": float(cells[1]), "sounder": cells[2], "navigation": cells[3],
                     "controller": cells[4], "height_true_cm": float(cells[5]), "max_true_cm": float(cells[6])})
    return rows


def draw(rows: list[dict], out: Path) -> None:
    """Two panels (no current, 0.2 m/s across), a group of bars per bottom, a bar per controller."""
    chosen = [r for r in rows if r["sounder"] == "ping" and r["navigation"] == "dvl"]
    bottoms = list(dict.fromkeys(r["bottom"] for r in chosen))
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2), sharey=True)
    width = 0.8 / len(CONTROLLERS)
    for ax, current in zip(axes, (0.0, 0.2)):
        for k, controller in enumerate(CONTROLLERS):
            values = []
            for bottom in bottoms:
                found = [r["height_true_cm"] for r in chosen
                         if r["bottom"] == bottom and r["controller"] == controller and r["current"] == current]
                values.append(found[0] if found else math.nan)
            x = np.arange(len(bottoms)) + (k - (len(CONTROLLERS) - 1) / 2) * width
            bars = ax.bar(x, values, width, color=COLOURS[controller], label=LABELS[controller])
            ax.bar_label(bars, fmt="%.1f", fontsize=7, padding=1)
        ax.axhline(GOAL, color="grey", linestyle=":", linewidth=1)
        ax.set_xticks(np.arange(len(bottoms)), [TICKS.get(b, b) for b in bottoms])
        ax.set_title("no current" if current == 0.0 else f"{current:g} m/s across the line")
        ax.grid(axis="y", alpha=0.3)
    axes[0].set_ylabel("height error vs true bottom, RMS (cm)")
    axes[0].annotate("5 cm: the goal on the real bottom", (-0.45, GOAL + 0.2), fontsize=8, color="grey")
    axes[1].legend(fontsize=8, loc="upper left")
    fig.suptitle("1 m above the bottom at 0.2 m/s, DVL navigation, Ping-like sounder (built-in vehicle)", fontsize=11)
    save(fig, out)


def main() -> None:
    redraw(__doc__.splitlines()[0], "tools/transect_table.py", read_rows, draw)


if __name__ == "__main__":
    main()
