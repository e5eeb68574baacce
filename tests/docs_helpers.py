"""The manual's checked example outputs, as the docs tests hold them: the block after a mark on a how-to page, a
printed line's words (its figures aside), and whether printed lines are what a block shows (`...` skips)."""

from __future__ import annotations

import re

from conftest import ROOT

HOWTO = ROOT / "docs" / "howto"
GAP = "..."


def example_after(page: str, mark: str) -> list[str]:
    """The lines of the fenced block right after the line holding `mark`, unindented."""
    lines = page.splitlines()
    start = next(i for i, line in enumerate(lines) if mark in line)
    fence = next(i for i in range(start + 1, len(lines)) if lines[i].strip().startswith("```"))
    end = next(i for i in range(fence + 1, len(lines)) if lines[i].strip().startswith("```"))
    indent = len(lines[fence]) - len(lines[fence].lstrip())
    return [line[indent:] for line in lines[fence + 1:end]]


def words(line: str) -> str:
    """A line with its figures (integers, decimals, signed) replaced by N and the spaces between its words (a
    table's alignment) collapsed; its indentation kept."""
    figures = re.sub(r"[-+]?\d+(\.\d+)?", "N", line.rstrip())
    return figures[:len(figures) - len(figures.lstrip())] + " ".join(figures.split())


def shows(shown: list[str], printed: list[str]) -> bool:
    """Whether the printed lines are the shown ones, word for word, `...` lines and ` ...` line ends aside."""
    pattern = []
    for line in shown:
        if line.strip() == GAP:
            pattern.append(r"(?:[^\n]*\n)*?")
        elif line.rstrip().endswith(" " + GAP):
            pattern.append(re.escape(words(line.rstrip()[:-len(GAP)])) + r"[^\n]*\n")
        else:
            pattern.append(re.escape(words(line)) + r"\n")
    return re.fullmatch("".join(pattern), "".join(words(line) + "\n" for line in printed)) is not None


def check(page: str, mark: str, printed: str) -> None:
    """The page's block after `mark` against what a command printed."""
    shown = example_after((HOWTO / page).read_text(), mark)
    assert shows(shown, printed.rstrip().splitlines()), f"{page} shows:\n" + "\n".join(shown) + \
        "\n\nthe command printed:\n" + printed
