"""The missions, scenario sets and vehicles that ship inside the package (rov_mav/data), found by name.

Wherever a command takes one of these files, an existing path is used as given; otherwise a bare name (no folder
in it) is looked up here: a mission by its stem (`square`) or file name (`under_ice_survey.plan`), a scenario set
by its stem (`robust_dive`), a vehicle by its stem (`ardusub_sitl`, `bluerov2_heavy`). In a checkout the
top-level missions/ and vehicles/ are links to these folders.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from rov_mav.config import ConfigError, read_yaml

KINDS = ("mission", "scenario set", "vehicle")


@dataclass(frozen=True)
class Shipped:
    name: str
    path: Path
    description: str


def data_folder() -> Path:
    return Path(str(resources.files("rov_mav") / "data"))


def _files(kind: str) -> list[Path]:
    data = data_folder()
    if kind == "mission":
        return sorted(p for p in (data / "missions").glob("*") if p.suffix in (".yaml", ".plan"))
    if kind == "scenario set":
        return sorted((data / "missions" / "scenarios").glob("*.yaml"))
    if kind == "vehicle":
        return sorted([data / "bluerov2_heavy.yaml", *(data / "vehicles").glob("*.yaml")])
    raise ValueError(kind)


def _name(path: Path) -> str:
    return path.name if path.suffix == ".plan" else path.stem   # a plan's stem is its YAML's


def _description(kind: str, path: Path) -> str:
    if path.suffix == ".plan":
        return "QGroundControl plan (its YAML of the same stem adds the environment and limits)"
    try:
        data = read_yaml(path)
    except ConfigError as exc:
        return f"(unreadable: {exc})"
    text = data.get("name" if kind == "vehicle" else "description") or ""
    return str(text).strip()


def listing(kind: str) -> list[Shipped]:
    """The shipped files of `kind`, by name, with a one-line description each."""
    return sorted((Shipped(_name(p), p, _description(kind, p)) for p in _files(kind)), key=lambda s: s.name)


def names(kind: str) -> list[str]:
    return sorted(_name(p) for p in _files(kind))


def label(path: str) -> str:
    """A shipped file's name (as `resolve` takes it), any other path as it is: for records such as bench.json."""
    shipped = {str(p): _name(p) for kind in KINDS for p in _files(kind)}
    return shipped.get(str(path), str(path))


def resolve(kind: str, text: str) -> str:
    """`text` if it is an existing path or names a folder (the file's loader reports it then); else the shipped
    file it names; ConfigError (one line, listing the names) if it names none."""
    if not text or os.path.lexists(text) or "/" in text or os.sep in text:
        return text
    for path in _files(kind):
        if text in (_name(path), path.name):
            return str(path)
    raise ConfigError(f"{text}: no such file, nor a shipped {kind} ({', '.join(names(kind))}; "
                      f"`rov-mav {'vehicles' if kind == 'vehicle' else 'missions'}` describes them)")
