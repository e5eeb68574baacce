"""The speed results page's figure, drawn from `tools/bench_particles.py`'s measurement (its rows, or the page's
table of them): CPU time per particle-step for each controller's closed loop on one thread, beside the plain C loop
of the same equations measured in the same rounds. Run:
    .venv/bin/python tools/particles_figure.py TABLE.txt --out docs/results/figures/particles.png
"""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from results_figure import markdown_rows, number, redraw, save

ONE_THREAD = "one thread: CPU ns per particle-step, min / median"


def read_rows(text: str) -> list[dict]:
    """controller, median ns per particle-step on one thread, ours / C (1 for C itself)."""
    return [{"controller": row["label"], "median": number(row[ONE_THREAD].split("/")[-1]),
             "ratio": number(row["ours / C"])} for row in markdown_rows(text) if ONE_THREAD in row]


def draw(rows: list[dict], out: Path) -> None:
    c = next(r for r in rows if r["controller"].startswith("C"))
    ours = [r for r in rows if r is not c]
    x = np.arange(len(ours))
    fig, ax = plt.subplots(figsize=(8, 3.8))
    bars = ax.bar(x, [r["median"] for r in ours], color="#1f77b4", label="rov-mav's compiled loop (one thread)")
    ax.bar_label(bars, labels=[f"{r['ratio']:.2f}× C" for r in ours], fontsize=8, padding=2)
    ax.axhline(c["median"], color="#d62728", linestyle="--", label=f"plain C loop: {c['median']:.0f} ns")
    ax.set_xticks(x, [r["controller"] for r in ours])
    ax.set_ylabel("CPU ns per particle-step (median)")
    ax.set_ylim(0, 1.25 * c["median"])
    ax.legend(fontsize=8, loc="lower right")
    ax.grid(axis="y", alpha=0.3)
    ax.set_title("One PSO iteration's batch: 100 particles × 60 s at 100 Hz on the line", fontsize=11)
    save(fig, out)


if __name__ == "__main__":
    redraw(__doc__.splitlines()[0], "tools/bench_particles.py", read_rows, draw)
