"""QGroundControl `.plan` files -> a Mission (the format: docs/en/qgc-dev-guide/file_formats/plan.md in QGC's
repository).

A plan is JSON with fileType "Plan" and a `mission` holding `items`. A SimpleItem is one MAVLink mission item as QGC
stores it: command, frame and params [param1..4, latitude, longitude, altitude] (null for NaN: e.g. "yaw
unchanged"). Survey and corridor-scan ComplexItems keep the waypoints QGC generated for them in
TransectStyleComplexItem.Items (QGC's `TransectStyleComplexItem::_appendWaypoint`: NAV_WAYPOINT, hold 0, yaw null,
altitude the scan's distance to surface); those are flown as they are. Other complex items (a structure scan, whose
waypoints QGC does not store; landing patterns) cannot be flown. Home is `plannedHomePosition` (lat, lon, AMSL alt);
the legs' speed is `cruiseSpeed`, which QGC uses for a vehicle that is neither a multirotor nor a VTOL, as a
submarine is (`MissionController::_resetMissionFlightStatus`). What the items mean: `mission_items`.

A plan has no environment or limits: run it as it is (still water, limits from the command's flags), or name it
from a mission YAML (`plan: FILE.plan`, relative to the YAML) that adds them (`PlanFileSchema`).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Annotated, Any

from pydantic import Field

from rov_mav import config
from rov_mav.mission.mission_items import MissionItem, Planned, PlanOptions, build_mission
from rov_mav.mission.missions import LimitsSchema, Mission
from rov_mav.model.environment import EnvironmentSchema

TRANSECT_TYPES = ("survey", "CorridorScan")
KIND_NAMES = {dict: "an object", list: "a list", int: "an integer"}
Positive = Annotated[float, Field(gt=0)]
LatLon = Annotated[list[float], Field(min_length=2, max_length=2)]


class PlanFileSchema(config.StrictModel):
    """A mission YAML that flies a QGroundControl plan and gives it what a plan lacks."""

    name: str
    description: str = ""
    plan: str                                   # the .plan file, relative to this YAML
    origin: LatLon | None = None                # lat, lon deg of local (0, 0); default the plan's home
    speed: Positive | None = None               # m/s; default the plan's cruiseSpeed
    skip_unflyable: bool = False
    ramp_time: Positive = 2.0
    environment: EnvironmentSchema = EnvironmentSchema()
    limits: LimitsSchema = LimitsSchema()


def load_plan(path: str | Path, options: PlanOptions = PlanOptions()) -> Mission:
    """The mission of a .plan file, in still water without limits; ConfigError (file, item, reason) if it is not
    one QGC writes or holds anything we would not fly."""
    path = Path(path)
    return build_mission(parse_plan(read_json(path), str(path), path.stem), options)


def load_plan_file(path: str | Path, data: dict[str, Any], options: PlanOptions = PlanOptions()) -> Mission:
    """The mission of a mission YAML (already read into `data`) that names a plan; command-line options win over
    the YAML's origin, speed and skip_unflyable."""
    spec = config.parse(PlanFileSchema, data, path)
    plan_path = Path(path).parent / spec.plan
    extra = {"description": spec.description, "ramp_time": spec.ramp_time,
             "environment": spec.environment.model_dump(), "limits": spec.limits.model_dump()}
    planned = parse_plan(read_json(plan_path), str(plan_path), spec.name, extra)
    merged = PlanOptions(origin=options.origin or (tuple(spec.origin) if spec.origin else None),
                         speed=options.speed or spec.speed,
                         skip_unflyable=options.skip_unflyable or spec.skip_unflyable)
    return build_mission(planned, merged)


def read_json(path: Path) -> Any:
    """The JSON in a small text file, read the guarded way every configuration file is (`config.read_text`)."""
    text = config.read_text(path, "JSON")
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise config.ConfigError(f"{path} (line {exc.lineno}): invalid JSON: {exc.msg}") from None
    except RecursionError:
        raise config.ConfigError(f"{path}: invalid JSON: nested too deep") from None


def parse_plan(data: Any, source: str, name: str, extra: dict | None = None) -> Planned:
    """The items, home and speed of a plan's JSON; ConfigError naming the key at fault."""
    if not isinstance(data, dict) or data.get("fileType") != "Plan":
        raise config.ConfigError(f"{source}: fileType: expected \"Plan\" (a QGroundControl plan file)")
    mission = _get(data, "mission", dict, source)
    raw_items = _get(mission, "items", list, source, "mission.")
    home = None
    if "plannedHomePosition" in mission:
        position = mission["plannedHomePosition"]
        if not (isinstance(position, list) and len(position) >= 2 and all(_is_number(v) for v in position[:2])):
            raise config.ConfigError(f"{source}: mission.plannedHomePosition: expected [latitude, longitude, "
                                     f"altitude]")
        home = (float(position[0]), float(position[1]))
    speed = mission.get("cruiseSpeed")
    if speed is not None and not _is_number(speed):
        raise config.ConfigError(f"{source}: mission.cruiseSpeed: expected a number (m/s)")
    items: list[MissionItem] = []
    for i, raw in enumerate(raw_items):
        where = f"mission.items[{i}]"
        if not isinstance(raw, dict):
            raise config.ConfigError(f"{source}: {where}: expected an object")
        kind = raw.get("type")
        if kind == "SimpleItem":
            items.append(_simple_item(raw, where, source))
        elif kind == "ComplexItem":
            items.extend(_complex_items(raw, where, source))
        else:
            raise config.ConfigError(f"{source}: {where}.type: expected \"SimpleItem\" or \"ComplexItem\"")
    return Planned(name=name, source=source, home=home, speed=None if speed is None else float(speed),
                   speed_origin="mission.cruiseSpeed", items=items, extra=extra or {})


def _simple_item(raw: dict, where: str, source: str) -> MissionItem:
    command = _get(raw, "command", int, source, f"{where}.")
    frame = _get(raw, "frame", int, source, f"{where}.")
    params = _get(raw, "params", list, source, f"{where}.")
    if len(params) != 7 or not all(v is None or _is_number(v) for v in params):
        raise config.ConfigError(f"{source}: {where}.params: expected 7 numbers or nulls")
    return MissionItem(where, command, frame, tuple(math.nan if v is None else float(v) for v in params))


def _complex_items(raw: dict, where: str, source: str) -> list[MissionItem]:
    kind = raw.get("complexItemType")
    if kind not in TRANSECT_TYPES:
        note = "QGC stores no waypoints in it" if kind == "StructureScan" else "not a survey or corridor scan"
        return [MissionItem(where, 0, 0, (math.nan,) * 7, kind=f"{kind} complex item: {note}")]
    transect = _get(raw, "TransectStyleComplexItem", dict, source, f"{where}.")
    inner = _get(transect, "Items", list, source, f"{where}.TransectStyleComplexItem.")
    if not inner:
        raise config.ConfigError(f"{source}: {where}.TransectStyleComplexItem.Items: empty (a plan saved by a QGC "
                                 f"older than 3.4 keeps no waypoints: open it in QGC and save it again)")
    return [_simple_item(item, f"{where}.TransectStyleComplexItem.Items[{j}]", source)
            if isinstance(item, dict) else _not_an_object(f"{where}.TransectStyleComplexItem.Items[{j}]", source)
            for j, item in enumerate(inner)]


def _not_an_object(where: str, source: str):
    raise config.ConfigError(f"{source}: {where}: expected an object")


def _get(obj: dict, key: str, kind: type, source: str, prefix: str = ""):
    if key not in obj:
        raise config.ConfigError(f"{source}: {prefix}{key}: missing")
    value = obj[key]
    if kind is int:
        ok = isinstance(value, int) and not isinstance(value, bool)
    else:
        ok = isinstance(value, kind)
    if not ok:
        raise config.ConfigError(f"{source}: {prefix}{key}: expected {KIND_NAMES[kind]}")
    return value


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
