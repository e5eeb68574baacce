"""Installed without a checkout: the built wheel, pip-installed (not editable) into a fresh venv, gives a working
`rov-mav` run from a folder outside the repository, with every shipped mission, scenario set and vehicle.

The wheel is built from a copy of the package sources (pyproject.toml, README.md, rov_mav/, sim_bridge/), so the
checkout gets no build/ or egg-info. The venv reaches the dependencies through a .pth line naming this
interpreter's site-packages (no download); a line in a .pth file adds a folder without running the .pth files in
it, so the checkout's editable install is not seen, and the test checks that rov_mav comes from the venv.

The mission is simulated with NUMBA_DISABLE_JIT=1: compiling the kernels in a fresh install takes about 50 s of
CPU, and every other test runs them compiled; what only this test can catch is what the wheel leaves out.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

pytestmark = pytest.mark.process      # starts a process or the bridge (tests/conftest.py)

ROOT = Path(__file__).resolve().parents[1]
SOURCES = ("pyproject.toml", "README.md", "rov_mav", "sim_bridge")


def _run(argv: list, cwd: Path, env: dict | None = None, timeout: float = 120) -> subprocess.CompletedProcess:
    done = subprocess.run([str(a) for a in argv], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=timeout, stdin=subprocess.DEVNULL)
    assert done.returncode == 0, f"{argv}: exit {done.returncode}\n{done.stdout}\n{done.stderr}"
    return done


def _tracked_data_files() -> set[str]:
    """The files of rov_mav/data in the checkout, relative to rov_mav/data (git's list where git is at hand)."""
    data = ROOT / "rov_mav" / "data"
    if shutil.which("git") and (ROOT / ".git").exists():
        listed = subprocess.run(["git", "ls-files", "rov_mav/data"], cwd=ROOT, capture_output=True, text=True,
                                check=True).stdout.split()
        return {str(Path(f).relative_to("rov_mav/data")) for f in listed}
    return {str(p.relative_to(data)) for p in data.rglob("*") if p.is_file() and "__pycache__" not in p.parts}


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """(venv folder, environment for its commands, a working folder outside the repository)."""
    tmp = tmp_path_factory.mktemp("wheel")
    src = tmp / "src"
    src.mkdir()
    for name in SOURCES:
        copy = shutil.copytree if (ROOT / name).is_dir() else shutil.copy2
        copy(ROOT / name, src / name, **({"ignore": shutil.ignore_patterns("__pycache__", "*.pyc")}
                                         if (ROOT / name).is_dir() else {}))
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--quiet", "-w", tmp / "dist", "./src"], tmp)
    wheel, = (tmp / "dist").glob("rov_mav-*.whl")
    venv = tmp / "venv"
    _run([sys.executable, "-m", "venv", "--without-pip", venv], tmp)
    python = venv / "bin" / "python"
    site = Path(_run([python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"], tmp).stdout.strip())
    ours = {sysconfig.get_paths()["purelib"], sysconfig.get_paths()["platlib"]}
    (site / "_dependencies.pth").write_text("".join(f"{p}\n" for p in sorted(ours)))
    _run([sys.executable, "-m", "pip", "--python", python, "install", "--no-deps", "--no-index", "--quiet", wheel], tmp)
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "NUMBA_", "VIRTUAL_ENV"))}
    env["NUMBA_DISABLE_JIT"] = "1"
    work = tmp / "work"
    work.mkdir()
    return venv, env, work


def test_the_package_comes_from_the_wheel(installed):
    venv, env, work = installed
    where = _run([venv / "bin" / "python", "-c", "import rov_mav, sim_bridge; print(rov_mav.__file__); "
                  "print(sim_bridge.__file__)"], work, env).stdout.split()
    assert all(Path(w).is_relative_to(venv) for w in where), where


def test_every_data_file_is_in_the_wheel(installed):
    """What the checkout holds in rov_mav/data, the installed package holds too (a new kind of file that the
    package-data patterns miss fails here)."""
    venv, env, work = installed
    data = Path(_run([venv / "bin" / "python", "-c", "from rov_mav import shipped; print(shipped.data_folder())"],
                     work, env).stdout.strip())
    shipped = {str(p.relative_to(data)) for p in data.rglob("*") if p.is_file()}
    assert _tracked_data_files() <= shipped, sorted(_tracked_data_files() - shipped)


def test_missions_and_vehicles_are_listed(installed):
    venv, env, work = installed
    listing = _run([venv / "bin" / "rov-mav", "missions"], work, env).stdout
    for name in ("identify", "line", "square", "under_ice_survey", "under_ice_survey.plan", "robust", "bench",
                 "robust_dive"):
        assert f"  {name} " in listing, listing
    assert "10 x 10 m pool square" in listing, listing
    vehicles = _run([venv / "bin" / "rov-mav", "vehicles"], work, env).stdout
    assert all(f"  {name} " in vehicles for name in ("bluerov2_heavy", "ardusub_sitl", "ardusub_sitl_prior")), vehicles


def test_a_shipped_mission_flies_by_name(installed):
    venv, env, work = installed
    done = _run([venv / "bin" / "rov-mav", "simulate", "line", "--duration", "4", "--rerun", "off", "--out", "line"],
                work, env)
    metrics = json.loads((work / "line" / "metrics.json").read_text())
    assert metrics["completed"] and metrics["mission"] == "line" and metrics["duration_s"] == pytest.approx(4.0)
    assert 0 < metrics["rms_position_error_m"] < 0.05, metrics
    assert "line / fuzzy: completed" in done.stdout


def test_a_shipped_plan_finds_its_plan_file(installed):
    """under_ice_survey is a YAML naming a .plan beside it: both must be in the wheel, side by side."""
    venv, env, work = installed
    _run([venv / "bin" / "rov-mav", "simulate", "under_ice_survey", "--duration", "2", "--rerun", "off",
          "--out", "survey"], work, env)
    assert json.loads((work / "survey" / "metrics.json").read_text())["completed"]


def test_an_unknown_name_is_one_line(installed):
    venv, env, work = installed
    done = subprocess.run([venv / "bin" / "rov-mav", "simulate", "sqare"], cwd=work, env=env, capture_output=True,
                          text=True, timeout=60, stdin=subprocess.DEVNULL)
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and done.stderr.startswith("rov-mav simulate: error: argument mission: "
                                                                  "sqare: no such file, nor a shipped mission ("), \
        done.stderr
    assert "square" in done.stderr
