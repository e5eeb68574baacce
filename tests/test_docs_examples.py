"""The manual's example outputs are what the commands print now: each example block marked as checked is held,
line by line, to the output of the commands its page gives (its words; the figures may differ from run to run),
so a page cannot show a summary the program no longer prints."""

from __future__ import annotations

import re
import subprocess

import pytest
from bridge_helpers import ROV_MAV
from conftest import ROOT

pytestmark = pytest.mark.process      # flies the square on the built-in vehicle
MARK = "<!-- checked against `rov-mav analyze` by tests/test_docs_examples.py"
WAIT = 300.0                          # wall s: the square at --speedup 10 is 23 s on an idle machine


def example_after(page: str, mark: str) -> list[str]:
    """The lines of the fenced block right after the line holding `mark`, unindented."""
    lines = page.splitlines()
    start = next(i for i, line in enumerate(lines) if mark in line)
    fence = next(i for i in range(start + 1, len(lines)) if lines[i].strip().startswith("```"))
    end = next(i for i in range(fence + 1, len(lines)) if lines[i].strip().startswith("```"))
    indent = len(lines[fence]) - len(lines[fence].lstrip())
    return [line[indent:] for line in lines[fence + 1:end]]


def words(line: str) -> str:
    """A line with its figures (integers, decimals, signed) replaced by N."""
    return re.sub(r"[-+]?\d+(\.\d+)?", "N", line.rstrip())


def test_words_hide_figures_only():
    assert words("  t = -8.5 s armed (MANUAL); T1 0.0 %") == "  t = N s armed (MANUAL); TN N %"
    assert words("position RMS") != words("position max")


def test_the_review_pages_summary_is_what_analyze_prints_for_the_square(tmp_path):
    page = (ROOT / "docs" / "howto" / "review-dive.md").read_text()
    shown = example_after(page, MARK)
    run = subprocess.run([ROV_MAV, "run", "square", "--speedup", "10", "--log", "out/square/log", "--rerun", "off"],
                         cwd=tmp_path, capture_output=True, text=True, timeout=WAIT)
    assert run.returncode == 0, run.stdout + run.stderr
    review = subprocess.run([ROV_MAV, "analyze", "out/square/log", "--rerun", "off"], cwd=tmp_path,
                            capture_output=True, text=True, timeout=WAIT)
    assert review.returncode == 0, review.stdout + review.stderr
    printed = review.stdout.rstrip().splitlines()
    assert [words(line) for line in shown] == [words(line) for line in printed], "\n".join(printed)
