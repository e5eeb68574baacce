"""The project stands on its own: no tracked file sends a reader, a tool or a test to a path outside the
repository (a sibling folder of the checkout, a folder of one machine, a design note kept elsewhere).
"""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
# Written in pieces so that this file does not match itself.
OUTSIDE = ("../" + "shared", "/" + "work/", "DESIGN" + ".md")
SKIPPED_FOLDERS = {".git", ".venv", "out", "build", "__pycache__", ".pytest_cache"}
# The one reference allowed: CI points the real-log tests at the logs folder beside the checkout, by a variable.
ALLOWED = {(".ci/run", "export ROVMAV_REAL_LOGS=")}


def tracked_files() -> list[Path]:
    """The files git tracks (what a clone holds); outside a git checkout, the tree less generated folders."""
    try:
        listed = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        return [p for p in ROOT.rglob("*") if p.is_file()
                and not SKIPPED_FOLDERS & set(p.relative_to(ROOT).parts) and ".egg-info" not in str(p)]
    return [ROOT / name for name in listed.decode().split("\0") if name]


def references_outside(path: Path) -> list[str]:
    """'LINE: text' for each line of a text file naming a place outside the repository."""
    if path.is_symlink() or not path.is_file():
        return []
    data = path.read_bytes()
    if b"\0" in data[:8192]:
        return []
    return [f"{n}: {line.strip()[:100]}" for n, line in enumerate(data.decode("utf-8", "replace").splitlines(), 1)
            if any(pattern in line for pattern in OUTSIDE)]


@pytest.mark.process
def test_the_file_list_is_the_repository():
    files = {p.relative_to(ROOT).as_posix() for p in tracked_files()}
    assert {"pyproject.toml", "rov_mav/cli.py", "tests/test_standalone.py"} <= files


@pytest.mark.process
def test_no_file_points_outside_the_repository():
    offenders = {}
    for path in tracked_files():
        name = path.relative_to(ROOT).as_posix()
        offenders |= {f"{name}:{hit}": None for hit in references_outside(path)
                      if not any(name == where and text in hit for where, text in ALLOWED)}
    assert not offenders, "paths outside the repository:\n" + "\n".join(offenders)


def test_the_check_finds_a_reference(tmp_path):
    sample = tmp_path / "note.md"
    sample.write_text("see the\nnotes in " + OUTSIDE[0] + "/spec for more\n")
    assert references_outside(sample) == [f"2: notes in {OUTSIDE[0]}/spec for more"]
