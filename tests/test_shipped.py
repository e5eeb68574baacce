"""Shipped missions, scenario sets and vehicles by name (`rov_mav.shipped`), and `rov-mav missions` / `vehicles`.

In-process (`cli.main`) from an empty working folder outside the repository; the installed wheel is
tests/test_wheel_install.py's."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from conftest import MISSIONS, ROOT

from rov_mav import cli, shipped
from rov_mav.config import ConfigError
from rov_mav.mission.loader import load
from rov_mav.model.vehicle import load_vehicle
from rov_mav.offline.scenarios import load_scenarios


@pytest.fixture
def elsewhere(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    return tmp_path


def rov_mav(argv, capsys) -> tuple[int, str, str]:
    try:
        status = cli.main(argv)
    except SystemExit as exc:
        status = exc.code
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def test_the_checkouts_folders_are_the_packages():
    """missions/ and vehicles/ at the top of a checkout are the package's own folders (links), so that
    `rov-mav run missions/square.yaml` in a checkout and `rov-mav run square` anywhere fly the same file."""
    data = shipped.data_folder()
    assert (ROOT / "missions").resolve() == (data / "missions").resolve()
    assert (ROOT / "vehicles").resolve() == (data / "vehicles").resolve()


@pytest.mark.parametrize("kind,name,file", [
    ("mission", "square", "missions/square.yaml"),
    ("mission", "square.yaml", "missions/square.yaml"),
    ("mission", "under_ice_survey", "missions/under_ice_survey.yaml"),
    ("mission", "under_ice_survey.plan", "missions/under_ice_survey.plan"),
    ("scenario set", "robust_dive", "missions/scenarios/robust_dive.yaml"),
    ("vehicle", "ardusub_sitl", "vehicles/ardusub_sitl.yaml"),
    ("vehicle", "bluerov2_heavy", "bluerov2_heavy.yaml"),
])
def test_a_name_resolves_to_the_shipped_file(elsewhere, kind, name, file):
    assert Path(shipped.resolve(kind, name)) == shipped.data_folder() / file


def test_an_existing_file_wins_over_a_name(elsewhere):
    (elsewhere / "square").write_text("mine")
    assert shipped.resolve("mission", "square") == "square"


@pytest.mark.parametrize("text", ["no/such/square", "./square", "", "/nowhere.yaml"])
def test_a_path_is_left_to_its_loader(elsewhere, text):
    assert shipped.resolve("mission", text) == text


def test_an_unknown_name_lists_the_shipped_ones(elsewhere):
    with pytest.raises(ConfigError) as info:
        shipped.resolve("mission", "sqare")
    assert str(info.value).startswith("sqare: no such file, nor a shipped mission (identify, kelp_transect, line, "
                                      "square, ")


def test_every_shipped_file_loads(elsewhere):
    for item in shipped.listing("mission"):
        assert load(shipped.resolve("mission", item.name)).duration > 0
    line = load(shipped.resolve("mission", "line"))
    for item in shipped.listing("scenario set"):
        assert load_scenarios(shipped.resolve("scenario set", item.name), line.environment), item.name
    for item in shipped.listing("vehicle"):
        assert load_vehicle(shipped.resolve("vehicle", item.name)).mass > 0


def test_missions_lists_every_file_of_the_folder_with_its_description(elsewhere, capsys):
    status, out, err = rov_mav(["missions"], capsys)
    assert status == 0 and err == ""
    files = [p for p in MISSIONS.iterdir() if p.is_file()] + list((MISSIONS / "scenarios").iterdir())
    for path in files:
        name = path.name if path.suffix == ".plan" else path.stem
        assert any(line.startswith(f"  {name} ") and len(line.split(maxsplit=1)) == 2 for line in out.splitlines()), \
            (name, out)
    assert "  square  " in out and "10 x 10 m pool square" in out


def test_vehicles_lists_the_shipped_vehicles(elsewhere, capsys):
    status, out, _ = rov_mav(["vehicles"], capsys)
    assert status == 0
    assert "  bluerov2_heavy  " in out and "  ardusub_sitl  " in out and "SIM_Submarine" in out


@pytest.mark.parametrize("argv,where", [
    (["run", "sqare"], "argument mission"),
    (["simulate", "sqare"], "argument mission"),
    (["tune", "sqare"], "argument mission"),
    (["analyze", "x.tlog", "--mission", "sqare"], "argument --mission"),
    (["bench", "--missions", "sqare"], "argument --missions"),
    (["sim-bridge", "--environment", "sqare"], "argument --environment"),
    (["simulate", "line", "--vehicle", "sqare"], "argument --vehicle"),
    (["tune", "line", "--scenarios", "sqare"], "argument --scenarios"),
])
def test_an_unknown_name_is_one_line_naming_the_argument(elsewhere, capsys, argv, where):
    status, out, err = rov_mav(argv, capsys)
    assert status == 2 and out == ""
    assert err.count("\n") == 1 and err.startswith(f"rov-mav {argv[0]}: error: {where}: sqare: no such file, nor "
                                                    "a shipped "), err
    assert os.listdir(elsewhere) == []


def test_a_mission_flies_by_name_from_anywhere(elsewhere, capsys):
    status, out, err = rov_mav(["simulate", "line", "--duration", "2", "--rerun", "off", "--out", "o"], capsys)
    assert status == 0, err
    assert "line / fuzzy: completed" in out and (elsewhere / "o" / "metrics.json").exists()


@pytest.mark.parametrize("command", ["run", "simulate", "tune"])
def test_help_says_a_name_or_a_file(capsys, command):
    with pytest.raises(SystemExit):
        cli.main([command, "--help"])
    page = " ".join(capsys.readouterr().out.split())
    assert "mission: a shipped mission's name (e.g. square;" in page and "lists them) or a file: our YAML" in page
