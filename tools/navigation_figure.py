"""The navigation results page's figure, drawn from `tools/navigation_table.py`'s own table (its markdown rows, as
it printed them): the position error against the truth (RMS, with the worse seed's max as a tick) per navigation
and controller, one panel per mission. Rows without a truth (ideal navigation) are left out. Run:
    .venv/bin/python tools/navigation_figure.py TABLE.txt [TABLE.txt ...] --out docs/results/figures/navigation.png
"""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from results_figure import redraw, save

ROWS = ("fuzzy", "fuzzy/model", "guided")
LABELS = {"fuzzy": "rov-mav fuzzy on the vehicle's estimate", "fuzzy/model": "rov-mav fuzzy on its own estimate",
          "guided": "ArduSub GUIDED"}
COLOURS = {"fuzzy": "#1f77b4", "fuzzy/model": "#6baed6", "guided": "#d62728"}
NAVIGATION = ("dvl", "ugps", "dvl+ugps")


def read_rows(text: str) -> list[dict]:
    """The table's data rows with a truth: mission, navigation, row, RMS and max against the truth (cm)."""
    rows = []
    for line in text.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) < 6 or cells[0] == "mission" or set(cells[0]) <= {"-"}:
            continue
        if cells[3] != "nan":                        # no truth on the link (ideal navigation)
            rows.append({"mission": cells[0], "navigation": cells[1], "row": cells[2], "rms": float(cells[3]),
                         "max": float(cells[4])})
    return rows


def draw(rows: list[dict], out: Path) -> None:
    missions = list(dict.fromkeys(r["mission"] for r in rows))
    fig, axes = plt.subplots(1, len(missions), figsize=(5.5 * len(missions), 4.2), sharey=True, squeeze=False)
    width = 0.8 / len(ROWS)
    for ax, mission in zip(axes[0], missions):
        for k, row in enumerate(ROWS):
            found = [[r for r in rows if r["mission"] == mission and r["navigation"] == nav and r["row"] == row]
                     for nav in NAVIGATION]
            rms = [f[0]["rms"] if f else math.nan for f in found]
            worst = [f[0]["max"] if f else math.nan for f in found]
            x = np.arange(len(NAVIGATION)) + (k - (len(ROWS) - 1) / 2) * width
            bars = ax.bar(x, rms, width, color=COLOURS[row], label=LABELS[row])
            ax.bar_label(bars, fmt="%.1f", fontsize=7, padding=1)
            ax.plot(x, worst, "_", color="k", markersize=10, label="max (worse seed)" if k == 0 else None)
        ax.set_xticks(np.arange(len(NAVIGATION)), NAVIGATION)
        ax.set_title(mission.replace("_", " "))
        ax.grid(axis="y", alpha=0.3)
    axes[0][0].set_ylabel("position error vs truth, RMS (cm)")
    axes[0][-1].legend(fontsize=8, loc="upper right")
    fig.suptitle("Position error against the truth per navigation (built-in vehicle, means of two seeds)",
                 fontsize=11)
    save(fig, out)


def main() -> None:
    redraw(__doc__.splitlines()[0], "tools/navigation_table.py", read_rows, draw)


if __name__ == "__main__":
    main()
