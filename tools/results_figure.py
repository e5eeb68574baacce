"""What the results pages' figure tools share: saving a figure as the manual shows it, and redrawing one from a
measuring tool's saved table (its markdown rows)."""

from __future__ import annotations

import argparse
import math
import re
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


def markdown_rows(text: str) -> list[dict[str, str]]:
    """Every data row of every markdown table in `text`, keyed by its table's header cells (backticks dropped); the
    first cell also under "label"."""
    rows: list[dict[str, str]] = []
    header: list[str] | None = None
    lines = text.splitlines()
    for i, line in enumerate(lines):
        cells = [c.strip().replace("`", "") for c in line.strip().strip("|").split("|")]
        if not line.strip().startswith("|"):
            header = None
        elif i + 1 < len(lines) and set(lines[i + 1].strip()) <= set("|-: ") and "-" in lines[i + 1]:
            header = cells
        elif header is not None and not set(line.strip()) <= set("|-: "):
            rows.append({"label": cells[0], **dict(zip(header, cells))})
    return rows


def number(cell: str) -> float:
    """The first figure in a cell ("0.96-1.06" -> 0.96, "**0.48**" -> 0.48, "-" -> nan)."""
    found = re.search(r"-?\d+(\.\d+)?", cell.replace("**", ""))
    return float(found.group(0)) if found else math.nan
