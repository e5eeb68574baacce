"""What the results pages' figure tools share: saving a figure as the manual shows it, and redrawing one from a
measuring tool's saved table (its markdown rows)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Callable

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def save(fig, out: Path) -> None:
    """Laid out, written at the manual's resolution, closed."""
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def redraw(description: str, tool: str, read_rows: Callable[[str], list[dict]],
           draw: Callable[[list[dict], Path], None]) -> None:
    """The command line of a figure tool: TABLE.txt ... --out PNG, the rows of every table drawn at once."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("tables", nargs="+", type=Path, help=f"{tool}'s saved output")
    parser.add_argument("--out", type=Path, required=True, help="the PNG to write")
    args = parser.parse_args()
    draw([row for table in args.tables for row in read_rows(table.read_text())], args.out)
