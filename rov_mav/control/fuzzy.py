"""Fuzzy adaptation rates (Sec. II.iv, Eq. 2.29, Appendix III): type-1 Mamdani inference per body DOF.

`MamdaniSystem.evaluate` is the full inference (Gaussian membership, min implication, max aggregation, centroid
defuzzification). Each DOF's system is a fixed map from one scalar input to gamma, so the compiled kernel reads it
from a table sampled here once (`FuzzySchedule.table`), with linear interpolation between samples.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from importlib import resources
from pathlib import Path
from typing import Annotated

import numpy as np
from pydantic import Field, field_validator

from rov_mav import config

PositiveFloat = Annotated[float, Field(gt=0, le=1e6)]
Width = Annotated[float, Field(ge=1e-6, le=1e6)]   # of a Gaussian set: narrower ones overflow (x - c) / w squared
MAX_POINTS = 100_000   # samples of a set or of the lookup table (the shipped rules use a few hundred)


class _RuleSchema(config.StrictModel):
    input: PositiveFloat
    input_width: Width
    output: PositiveFloat
    output_width: Width


class _GroupSchema(config.StrictModel):
    dofs: Annotated[list[Annotated[int, Field(ge=0, le=5)]], Field(min_length=1, max_length=6)]
    input_gain: PositiveFloat
    rules: Annotated[list[_RuleSchema], Field(min_length=1)]


class _FuzzySchema(config.StrictModel):
    output_points: Annotated[int, Field(ge=11, le=MAX_POINTS)]
    table_points: Annotated[int, Field(ge=3, le=MAX_POINTS)]
    groups: dict[str, _GroupSchema]

    @field_validator("groups")
    @classmethod
    def _cover_each_dof_once(cls, groups: dict[str, _GroupSchema]) -> dict[str, _GroupSchema]:
        dofs = sorted(d for g in groups.values() for d in g.dofs)
        if dofs != list(range(6)):
            raise ValueError("the groups' dofs must cover 0..5 exactly once each")
        return groups


@dataclass(frozen=True)
class MamdaniSystem:
    """One-input, one-output Mamdani system with Gaussian sets: IF x is A_j THEN y is B_j (Eq. 2.29)."""

    input_centres: np.ndarray
    input_widths: np.ndarray
    output_centres: np.ndarray
    output_widths: np.ndarray
    output_points: int = 801

    @property
    def output_universe(self) -> np.ndarray:
        """Samples of y covering every consequent to +-4 widths (clipped at 0: a rate is non-negative)."""
        lo = max(0.0, float(np.min(self.output_centres - 4 * self.output_widths)))
        hi = float(np.max(self.output_centres + 4 * self.output_widths))
        return np.linspace(lo, hi, self.output_points)

    def firing(self, x: np.ndarray) -> np.ndarray:
        """Rule strengths w_j(x) = exp(-(x - a_j)^2 / (2 sigma_j^2)); (...,) -> (..., rules)."""
        x = np.asarray(x, dtype=float)[..., None]
        return np.exp(-0.5 * ((x - self.input_centres) / self.input_widths) ** 2)

    def evaluate(self, x: np.ndarray) -> np.ndarray:
        """Crisp output for inputs x (...,): min implication, max aggregation, centroid defuzzification.

        Inputs are clamped to the range of the rule centres."""
        x = np.clip(x, self.input_centres.min(), self.input_centres.max())
        y = self.output_universe
        consequents = np.exp(-0.5 * ((y[:, None] - self.output_centres) / self.output_widths) ** 2)  # (Y, rules)
        clipped = np.minimum(self.firing(x)[..., None, :], consequents)                          # (..., Y, rules)
        aggregate = clipped.max(axis=-1)                                                          # (..., Y)
        return (aggregate * y).sum(axis=-1) / aggregate.sum(axis=-1)


@dataclass(frozen=True)
class FuzzySchedule:
    """The six per-DOF systems and the gains that scale their inputs: gamma_i = FIS_i(gain_i |x_i|)."""

    systems: tuple[MamdaniSystem, ...]   # one per DOF, index 0..5
    input_gains: np.ndarray              # (6,)
    table_points: int

    def rates(self, grad: np.ndarray) -> np.ndarray:
        """Exact gamma (..., 6) for the adaptation direction grad = (J M^-1)^T s (..., 6)."""
        grad = np.abs(np.asarray(grad, dtype=float))
        return np.stack([self.systems[i].evaluate(self.input_gains[i] * grad[..., i]) for i in range(6)], -1)

    @property
    def table_xmax(self) -> np.ndarray:
        """Raw |grad_i| at which each table ends (the largest rule centre over the input gain), (6,)."""
        return np.array([s.input_centres.max() for s in self.systems]) / self.input_gains

    @property
    def table_scale(self) -> np.ndarray:
        """Table samples per unit of raw |grad_i|, (6,): the kernel's index is |grad_i| times this."""
        return (self.table_points - 1) / self.table_xmax

    @cached_property
    def table(self) -> np.ndarray:
        """gamma sampled at table_points uniform raw inputs in [0, table_xmax_i], (6, table_points).

        Built once per schedule; DOFs sharing a system and an input gain share the computation."""
        u = np.linspace(0.0, 1.0, self.table_points)
        rows: dict[tuple[int, float], np.ndarray] = {}
        for i in range(6):
            key = (id(self.systems[i]), float(self.input_gains[i]))
            if key not in rows:
                rows[key] = self.systems[i].evaluate(self.input_gains[i] * u * self.table_xmax[i])
        return np.stack([rows[(id(self.systems[i]), float(self.input_gains[i]))] for i in range(6)])


def default_rules_path() -> Path:
    """The shipped rule base (Appendix III)."""
    return Path(str(resources.files("rov_mav") / "data" / "fuzzy_rules.yaml"))


def load_fuzzy(path: str | Path | None = None) -> FuzzySchedule:
    """Load a rule-base file (default: Appendix III); ConfigError with file, key and reason on bad input."""
    path = Path(path) if path is not None else default_rules_path()
    spec = config.load(_FuzzySchema, path)
    systems: list[MamdaniSystem | None] = [None] * 6
    gains = np.zeros(6)
    for group in spec.groups.values():
        system = MamdaniSystem(
            input_centres=np.array([r.input for r in group.rules]),
            input_widths=np.array([r.input_width for r in group.rules]),
            output_centres=np.array([r.output for r in group.rules]),
            output_widths=np.array([r.output_width for r in group.rules]),
            output_points=spec.output_points,
        )
        for dof in group.dofs:
            systems[dof] = system
            gains[dof] = group.input_gain
    schedule = FuzzySchedule(systems=tuple(systems), input_gains=gains, table_points=spec.table_points)
    if not np.isfinite(schedule.table).all():
        raise config.ConfigError(f"{path}: groups: the membership functions are too narrow: some inputs fire no rule "
                                 "and the centroid is undefined")
    return schedule
