"""Tuning scenarios: the conditions a gain set is scored under (disturbance, current, noise, model error).

A scenarios file lists entries; each may replace the mission's `environment` block (same keys as a mission's),
scale the simulated plant against the controller's model (mass, inertia, added mass, damping: `plant_scale`
1.2 is a plant 20 % heavier than the model), seed the sensor noise, limit each thruster's thrust (`max_thrust`, N:
the bench clips the wrench to what such thrusters can give) and name the group it reports under (`group`).
Shipped sets (`rov-mav missions`): robust (the tuning set), bench (the bench's held-out set), in rov_mav/data/missions/
scenarios/.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

from pydantic import Field

from rov_mav import config
from rov_mav.model.environment import Environment, EnvironmentSchema


class _ScenarioSchema(config.StrictModel):
    name: str
    environment: EnvironmentSchema | None = None               # None: the mission's own
    plant_scale: Annotated[float, Field(gt=0.2, lt=5.0)] = 1.0
    seed: Annotated[int, Field(ge=0, le=2**31)] = 0   # the bench's N runs use seed, seed + 1, ...
    max_thrust: Annotated[float, Field(gt=0, le=100)] | None = None   # N per thruster; None: the mission's limit
    group: str | None = None                                           # None: the scenario's name


class _ScenariosFile(config.StrictModel):
    description: str = ""      # one line, for `rov-mav missions`
    scenarios: Annotated[list[_ScenarioSchema], Field(min_length=1)]


@dataclass(frozen=True)
class Scenario:
    name: str
    environment: Environment
    plant_scale: float   # true plant = model.scaled(plant_scale)
    seed: int            # sensor-noise seed
    max_thrust: float | None = None   # N per thruster (None: the mission's limit)
    group: str = "nominal"            # the bench's reporting group (a file's entries default to their name)


def nominal(environment: Environment, seed: int = 0) -> Scenario:
    """The mission as written: its environment, a plant equal to the model."""
    return Scenario("nominal", environment, 1.0, seed)


def load_scenarios(path: str | Path, mission_environment: Environment) -> list[Scenario]:
    """Scenarios from a file; entries without `environment` take the mission's. ConfigError on bad input."""
    spec = config.load(_ScenariosFile, path)
    names = [s.name for s in spec.scenarios]
    duplicates = sorted({n for n in names if names.count(n) > 1})
    if duplicates:
        raise config.ConfigError(f"{path}: scenarios: duplicate name '{duplicates[0]}'")
    return [Scenario(s.name,
                     mission_environment if s.environment is None else Environment.from_schema(s.environment),
                     s.plant_scale, s.seed, s.max_thrust, s.group or s.name)
            for s in spec.scenarios]
