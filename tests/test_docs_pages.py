"""The user's pages (get started, first dive, how-to, reference) say what to do, not the project's history: no
commit hashes, no story of a defect (a flaky test, a fix, an older version). That history is the commit log's.
Every results page opens with its figure, right under its title."""

from __future__ import annotations

import re

import pytest
from conftest import ROOT

DOCS = ROOT / "docs"
USER_PAGES = sorted([DOCS / "get-started.md", DOCS / "first-dive.md", *(DOCS / "howto").glob("*.md"),
                     *(DOCS / "reference").glob("*.md")])
COMMIT = re.compile(r"\b(?=[0-9a-f]*[a-f])(?=[0-9a-f]*\d)[0-9a-f]{7,40}\b")
HISTORY = re.compile(r"flaky|older version|earlier version|previous version|used to |was fixed|before the fix|"
                     r"regression|a bug\b", re.IGNORECASE)


def test_the_user_pages_are_found():
    assert len(USER_PAGES) > 15 and all(page.exists() for page in USER_PAGES)


@pytest.mark.parametrize("page", USER_PAGES, ids=lambda p: str(p.relative_to(DOCS)))
def test_a_user_page_carries_no_commit_hash_and_no_defect_history(page):
    found = [f"{n}: {m.group(0)!r}" for n, line in enumerate(page.read_text().splitlines(), 1)
             for m in (*COMMIT.finditer(line), *HISTORY.finditer(line))]
    assert not found, found


@pytest.mark.parametrize("text", ["as of 3aa34ff the run", "before, a flaky test found it", "it used to drift"])
def test_the_check_catches_what_it_is_for(text):
    assert COMMIT.search(text) or HISTORY.search(text)


RESULTS_PAGES = sorted(page for page in (DOCS / "results").glob("*.md") if page.name != "index.md")
FIGURE = re.compile(r"^!\[[^\]]+\]\(([^)]+\.(?:png|svg))\)$")


def opening_figure(page) -> str | None:
    """The image a page shows first, if the first thing under its title is one: its path relative to the page."""
    lines = [line.strip() for line in page.read_text().splitlines() if line.strip()]
    found = FIGURE.match(lines[1]) if len(lines) > 1 and lines[0].startswith("# ") else None
    return found.group(1) if found else None


def test_the_results_pages_are_found():
    assert len(RESULTS_PAGES) >= 10


@pytest.mark.parametrize("page", RESULTS_PAGES, ids=lambda p: p.name)
def test_a_results_page_opens_with_a_figure_that_exists(page):
    figure = opening_figure(page)
    assert figure is not None, f"{page.name}: the first thing under the title is not a figure"
    assert (page.parent / figure).is_file(), f"{page.name}: {figure} is missing"


def test_the_figure_check_needs_the_figure_first(tmp_path):
    table_first = tmp_path / "table.md"
    table_first.write_text("# Title\n\n| a | b |\n|---|---|\n\n![plot](figures/x.png)\n")
    figure_first = tmp_path / "figure.md"
    figure_first.write_text("# Title\n\n![plot](figures/x.png)\n\nText.\n")
    assert opening_figure(table_first) is None and opening_figure(figure_first) == "figures/x.png"
