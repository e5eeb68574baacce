"""Any mission file -> a Mission: a QGroundControl `.plan`, a mission YAML naming a plan (`plan:`), or a mission
YAML with its own path."""

from __future__ import annotations

from pathlib import Path

from rov_mav import config
from rov_mav.mission.mission_items import PlanOptions
from rov_mav.mission.missions import Mission, mission_from_dict
from rov_mav.mission.qgc_plan import load_plan, load_plan_file


def load(path: str | Path, options: PlanOptions = PlanOptions()) -> Mission:
    """The mission in `path`; `options` apply to a plan (ignored for a YAML path). ConfigError before anything
    runs."""
    if Path(path).suffix.lower() == ".plan":
        return load_plan(path, options)
    data = config.read_yaml(path)
    if "plan" in data:
        return load_plan_file(path, data, options)
    return mission_from_dict(data, str(path))
