"""The manual's example outputs are what the commands print now: each example block marked as checked is held,
line by line, to the output of the commands its page gives (its words; the figures may differ from run to run),
so a page cannot show a summary the program no longer prints.

A block may be an excerpt: a line `...` stands for any run of printed lines (none included), and a line ending in
` ...` for a printed line that begins with its words. The square is flown once for the fly and the review pages."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest
from bridge_helpers import ROV_MAV
from docs_helpers import GAP, HOWTO, check, example_after, shows, words

pytestmark = pytest.mark.process      # every check runs the command its page gives, as a process
MARK = "<!-- checked against `rov-mav analyze` by tests/test_docs_examples.py"
WAIT = 300.0                          # wall s: the square at --speedup 5 is 46 s on an idle machine
# Each checked block of the how-to pages: (page, the start of its mark) -> the test file that holds it (which must
# name the mark). A mark no test holds fails test_every_checked_block_is_held_by_a_test.
CHECKED = {
    ("review-dive.md", MARK): "test_docs_examples.py",
    ("fly.md", "<!-- checked against `rov-mav run square`"): "test_docs_examples.py",
    ("simulate.md", "<!-- checked against `rov-mav simulate square`"): "test_docs_examples.py",
    ("qgc-plan.md", "<!-- checked against `rov-mav simulate under_ice_survey.plan`"): "test_docs_examples.py",
    ("tune.md", "<!-- checked against `rov-mav tune line`"): "test_docs_examples.py",
    ("cluster.md", "<!-- checked against `rov-mav tune line --cluster`"): "test_docs_examples.py",
    ("bench.md", "<!-- checked against `rov-mav bench`"): "test_docs_examples.py",
    ("autotune.md", "<!-- checked against `rov-mav autotune --dry-run`"): "test_autotune.py",
    ("identify.md", "<!-- checked against `rov-mav identify`"): "test_docs_examples.py",
    ("identify.md", "<!-- checked against the outcome of `rov-mav identify`"): "test_docs_examples.py",
}


def rov_mav(args: list[str], cwd: Path, status: int | None = 0) -> subprocess.CompletedProcess:
    """`rov-mav ARGS` in `cwd`, its exit status held to `status` (None: any)."""
    done = subprocess.run([ROV_MAV, *args], cwd=cwd, capture_output=True, text=True, timeout=WAIT)
    assert status is None or done.returncode == status, done.stdout + done.stderr
    return done


def test_words_hide_figures_only():
    assert words("  t = -8.5 s armed (MANUAL); T1 0.0 %") == "  t = N s armed (MANUAL); TN N %"
    assert words("position RMS") != words("position max")
    assert words("  surge    140.55  +/-0.52") == words("  surge 13.8 +/-0.154")


def test_an_excerpt_skips_only_where_it_says():
    printed = ["head 1", "a 2", "b 3", "tail 4 and more"]
    assert shows(["head 9", GAP, "tail 1 and more"], printed)
    assert shows(["head 9", "a 1", "b 1", "tail ..."], printed)
    assert shows(["head 9", GAP, "a 1", "b 1", GAP, "tail 1 and more"], printed)
    assert not shows(["head 9", "tail 1 and more"], printed)              # lines left out without a `...`
    assert not shows(["head 9", GAP, "tail 1"], printed)                  # a line cut short without a ` ...`
    assert not shows(["a 1", GAP], printed)                               # the first line is the first printed


def test_every_checked_block_is_held_by_a_test():
    marked = {(page.name, line.strip()) for page in HOWTO.glob("*.md") for line in page.read_text().splitlines()
              if line.strip().startswith("<!-- checked against")}
    held = {(page, line) for page, line in marked for name, mark in CHECKED if page == name and mark in line}
    assert marked == held, sorted(marked - held)
    assert all(any(name == page and mark in line for page, line in marked) for name, mark in CHECKED)
    tests = Path(__file__).parent
    assert all(mark in (tests / holder).read_text() for (_, mark), holder in CHECKED.items())


def test_the_fly_and_review_pages_show_what_run_and_analyze_print_for_the_square(tmp_path):
    """One flight of the square on the built-in vehicle at 5x, as both pages give it: the fly page's run, then the
    review page's summary of its log."""
    run = rov_mav(["run", "square", "--speedup", "5", "--log", "out/square/log", "--rerun", "off"], tmp_path)
    check("fly.md", "<!-- checked against `rov-mav run square`", run.stdout)
    review = rov_mav(["analyze", "out/square/log", "--rerun", "off"], tmp_path)
    check("review-dive.md", MARK, review.stdout)


def test_the_simulate_pages_summary_is_what_simulate_prints_for_the_square(tmp_path):
    done = rov_mav(["simulate", "square", "--rerun", "off"], tmp_path)
    check("simulate.md", "<!-- checked against `rov-mav simulate square`", done.stdout)


def test_the_plan_pages_summary_is_what_simulate_prints_for_the_shipped_plan(tmp_path):
    done = rov_mav(["simulate", "under_ice_survey.plan", "--rerun", "off"], tmp_path)
    check("qgc-plan.md", "<!-- checked against `rov-mav simulate under_ice_survey.plan`", done.stdout)


def test_the_tune_pages_summary_is_what_a_short_tune_prints(tmp_path):
    done = rov_mav(["tune", "line", "--particles", "20", "--iterations", "10", "--rerun", "off"], tmp_path)
    check("tune.md", "<!-- checked against `rov-mav tune line`", done.stdout)


def test_the_cluster_pages_summary_is_what_the_short_tune_prints_on_a_local_cluster(tmp_path):
    done = rov_mav(["tune", "line", "--particles", "20", "--iterations", "10", "--rerun", "off", "--cluster",
                    "local:2"], tmp_path)
    check("cluster.md", "<!-- checked against `rov-mav tune line --cluster`", done.stdout)


def test_the_bench_pages_summary_is_what_a_small_bench_prints(tmp_path):
    done = rov_mav(["bench", "--controllers", "fuzzy", "pid", "--missions", "line", "--seeds", "1", "--tune-budget",
                    "4x2", "--out", "out/bench-try"], tmp_path)
    check("bench.md", "<!-- checked against `rov-mav bench`", done.stdout)


def test_the_identify_pages_report_is_what_identify_prints_for_the_excitation_flown_on_the_built_in_vehicle(
        tmp_path):
    rov_mav(["run", "identify", "--gains", "report", "--speedup", "5", "--log", "out/identify", "--rerun", "off"],
            tmp_path)
    fit = rov_mav(["identify", "out/identify", "--out", "my_rov.yaml"], tmp_path, status=None)
    check("identify.md", "<!-- checked against `rov-mav identify`", fit.stdout)
    # The model the built-in vehicle flies is the prior itself: the fit may or may not beat it, and the page shows
    # both endings (written, exit 0; refused, exit 1, one line on stderr).
    assert fit.returncode in (0, 1), fit.stdout + fit.stderr
    assert (tmp_path / "my_rov.yaml").exists() == (fit.returncode == 0), fit.stdout + fit.stderr
    outcome = [line for line in fit.stdout.splitlines() if line.startswith("wrote ")] if fit.returncode == 0 \
        else fit.stderr.splitlines()
    endings = example_after((HOWTO / "identify.md").read_text(),
                            "<!-- checked against the outcome of `rov-mav identify`")
    assert len(outcome) == 1 and any(shows([ending], outcome) for ending in endings), (outcome, endings)
