"""The soak results page's figure, drawn from `tools/soak.py`'s own table (its markdown rows, as it printed them):
per window of vehicle time, the control rate and the tracking error (left) and both processes' memory (right).
Run:
    .venv/bin/python tools/soak_figure.py TABLE.txt --out docs/results/figures/soak.png
"""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
from results_figure import markdown_rows, number, redraw, save


def read_rows(text: str) -> list[dict]:
    return [{key: number(row[key]) for key in ("from (min)", "control rate (Hz)", "RMS error (cm)",
                                               "runner RSS (MB)", "bridge RSS (MB)")}
            for row in markdown_rows(text) if "runner RSS (MB)" in row]


def draw(rows: list[dict], out: Path) -> None:
    t = [r["from (min)"] for r in rows]
    fig, (rate, memory) = plt.subplots(1, 2, figsize=(11, 3.8))
    rate.plot(t, [r["control rate (Hz)"] for r in rows], "o-", color="#1f77b4", label="control rate (Hz)")
    rate.set_ylim(0, 55)
    rate.set_ylabel("control rate (Hz)")
    error = rate.twinx()
    error.plot(t, [r["RMS error (cm)"] for r in rows], "s--", color="#d62728", label="RMS error (cm)")
    error.set_ylabel("RMS error over the window (cm)", color="#d62728")
    error.set_ylim(bottom=0)
    rate.set_xlabel("vehicle time at the window's start (min)")
    rate.set_title("the loop over the hour")
    rate.grid(alpha=0.3)
    for who, colour in (("runner", "#1f77b4"), ("bridge", "#2ca02c")):
        memory.plot(t, [r[f"{who} RSS (MB)"] for r in rows], "o-", color=colour, label=f"{who} RSS")
    memory.set_ylim(0, 1.2 * max(r["runner RSS (MB)"] for r in rows))
    memory.set_xlabel("vehicle time at the window's start (min)")
    memory.set_ylabel("resident memory (MB)")
    memory.set_title("memory over the hour")
    memory.legend(loc="lower right", fontsize=8)
    memory.grid(alpha=0.3)
    save(fig, out)


if __name__ == "__main__":
    redraw(__doc__.splitlines()[0], "tools/soak.py", read_rows, draw)
