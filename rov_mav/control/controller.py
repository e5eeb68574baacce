"""Controller settings (kind, parameters) and the stateful controller the runner steps once per tick.

The laws are compiled (`rov_mav.control.law_kernel`, shared with simulate and tune); this module names their
parameter vectors. Each family of laws ships its defaults in rov_mav/data (`Family.file`); a --gains file may
override any of its family's keys. PSO tunes the leading groups of the vector (`Family.tuned`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property
from importlib import resources
from pathlib import Path
from typing import Annotated, Any

import numpy as np
from pydantic import Field, create_model

from rov_mav import config
from rov_mav.control import backstepping, ismc, law_kernel, pid, smc
from rov_mav.control.fuzzy import FuzzySchedule, load_fuzzy
from rov_mav.model import kernel
from rov_mav.model.vehicle import Vehicle

PositiveVec6 = Annotated[list[Annotated[float, Field(gt=0)]], Field(min_length=6, max_length=6)]
NonNegativeVec6 = Annotated[list[Annotated[float, Field(ge=0)]], Field(min_length=6, max_length=6)]
PositiveScalar = Annotated[float, Field(gt=0, le=1e6)]


@dataclass(frozen=True)
class Family:
    """A law's parameter vector: named groups in kernel order, the leading ones tuned, the default search box."""

    name: str
    file: str                                   # shipped defaults, in rov_mav/data
    groups: tuple[tuple[str, int], ...]         # (name, size) in the order of the kernel's vector
    tuned: tuple[str, ...]                      # the leading groups PSO tunes
    bounds: dict[str, tuple[Any, Any]]          # per tuned group: (lower, upper), scalars or 6 values each
    nonnegative: tuple[str, ...] = ()           # groups that may be 0 (the rest must be positive)

    @cached_property
    def schema(self) -> type[config.StrictModel]:
        """The gains file's schema: any of the groups, each validated."""
        def kind(name: str, size: int):
            if size == 1:
                return PositiveScalar
            return NonNegativeVec6 if name in self.nonnegative else PositiveVec6
        fields = {name: (kind(name, size) | None, None) for name, size in self.groups}
        return create_model(f"_{self.name}_gains", __base__=config.StrictModel, **fields)

    @property
    def n_tuned(self) -> int:
        return sum(size for name, size in self.groups if name in self.tuned)

    def default_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """The PSO box (lower, upper) of the tuned vector."""
        lower = np.concatenate([np.broadcast_to(self.bounds[g][0], (6,)) for g in self.tuned]).astype(float)
        upper = np.concatenate([np.broadcast_to(self.bounds[g][1], (6,)) for g in self.tuned]).astype(float)
        return lower, upper


def _family(name: str, file: str, module, nonnegative: tuple[str, ...] = ()) -> Family:
    return Family(name, file, module.PARAMETERS, module.TUNED, module.BOUNDS, nonnegative)


BACKSTEPPING = _family("backstepping", "controller.yaml", backstepping)
PID = _family("pid", "pid.yaml", pid, nonnegative=("ki_vel", "kd_vel", "i_max"))
SMC = _family("smc", "smc.yaml", smc)
ISMC = _family("ismc", "ismc.yaml", ismc)

# The report's law's kinds ship our PSO's k1, k2 over the family's file, whose k1, k2 are the report's own optimum
# (Eqs. 4.1-4.2), flown with `--gains report`.
KIND_GAINS = {"baseline": "baseline.yaml", "constant": "constant.yaml", "fuzzy": "fuzzy.yaml"}
REPORT_GAINS = "report"

# --controller NAME: (kernel kind id, family)
KINDS = {"baseline": (law_kernel.KIND_BASELINE, BACKSTEPPING), "constant": (law_kernel.KIND_CONSTANT, BACKSTEPPING),
         "fuzzy": (law_kernel.KIND_FUZZY, BACKSTEPPING), "pid": (law_kernel.KIND_PID, PID),
         "smc": (law_kernel.KIND_SMC, SMC), "ismc": (law_kernel.KIND_ISMC, ISMC)}


@dataclass(frozen=True)
class ControllerSettings:
    """Everything that defines a controller apart from the vehicle model: its kind and its named parameters.

    The parameter groups read as attributes (settings.k1, settings.kp_vel...)."""

    kind: str                       # a key of KINDS
    params: dict[str, np.ndarray]   # group name -> values, every group of the family
    fuzzy: FuzzySchedule            # the rate table (used by the fuzzy kind only)

    def __getattr__(self, name: str) -> np.ndarray:
        params = self.__dict__.get("params", {})
        if name in params:
            return params[name]
        raise AttributeError(name)

    @property
    def family(self) -> Family:
        return KINDS[self.kind][1]

    @property
    def vector(self) -> np.ndarray:
        """The kernel's flat parameter vector."""
        return np.concatenate([np.atleast_1d(self.params[name]) for name, _ in self.family.groups]).astype(float)

    @property
    def gains(self) -> np.ndarray:
        """The tuned part of the vector (its leading entries), e.g. [k1 | k2] (12,): what PSO tunes."""
        return self.vector[:self.family.n_tuned]

    def with_gains(self, gains: np.ndarray) -> "ControllerSettings":
        params = dict(self.params)
        start = 0
        for name, size in self.family.groups:
            if name in self.family.tuned:
                params[name] = np.asarray(gains[start:start + size], float)
                start += size
        return replace(self, params=params)

    def kernel_arguments(self) -> tuple:
        """(kind, table, table_scale) as the kernel takes them beside the parameter vector."""
        return (KINDS[self.kind][0], self.fuzzy.table, self.fuzzy.table_scale)

    def as_yaml(self) -> dict[str, Any]:
        """Every group as plain numbers: a gains file that reproduces this controller."""
        return {name: (float(self.params[name]) if size == 1 else np.asarray(self.params[name]).tolist())
                for name, size in self.family.groups}


def default_controller_path(family: Family = BACKSTEPPING) -> Path:
    return Path(str(resources.files("rov_mav") / "data" / family.file))


def default_gains_paths(kind: str) -> list[Path]:
    """The shipped files a kind's settings come from, in order: its family's, then its own gains (if any)."""
    family = KINDS[kind][1]
    own = [Path(str(resources.files("rov_mav") / "data" / KIND_GAINS[kind]))] if kind in KIND_GAINS else []
    return [default_controller_path(family), *own]


def load_settings(kind: str = "fuzzy", gains_file: str | Path | None = None,
                  fuzzy_file: str | Path | None = None, k1: list[float] | None = None,
                  k2: list[float] | None = None) -> ControllerSettings:
    """Shipped defaults, overridden by a gains file (`report`: the report's Eqs. 4.1-4.2 for its law), overridden by
    explicit k1/k2 (backstepping only, e.g. from the command line)."""
    if kind not in KINDS:
        raise config.ConfigError(f"controller: unknown kind '{kind}' (choose from {', '.join(KINDS)})")
    family = KINDS[kind][1]
    merged = {}
    for path in default_gains_paths(kind):
        merged.update(config.load(family.schema, path).model_dump(exclude_none=True))
    if gains_file is not None and str(gains_file) == REPORT_GAINS:
        if family is not BACKSTEPPING:
            raise config.ConfigError(f"--gains {REPORT_GAINS}: the report's gains (Eqs. 4.1-4.2) are its law's "
                                     f"(baseline, constant, fuzzy), not {kind}'s")
        gains_file = default_controller_path(family)
    if gains_file is not None:
        merged.update(config.load(family.schema, gains_file).model_dump(exclude_none=True))
    for name, value in (("k1", k1), ("k2", k2)):
        if value is None:
            continue
        if family is not BACKSTEPPING:
            raise config.ConfigError(f"--{name}: a gain of the backstepping law (baseline, constant, fuzzy); "
                                     f"--controller {kind} takes its gains from --gains")
        config.parse(family.schema, {name: [float(v) for v in value]}, f"--{name}")
        merged[name] = list(value)
    missing = [name for name, _ in family.groups if merged.get(name) is None]
    if missing:
        raise config.ConfigError(f"{default_controller_path(family)}: {missing[0]}: missing")
    params = {name: np.array(merged[name], float) for name, _ in family.groups}
    return ControllerSettings(kind=kind, params=params, fuzzy=load_fuzzy(fuzzy_file))


@dataclass(frozen=True)
class ControlOutput:
    """One tick of the controller: the wrench and the internals worth logging (zeros where a law has none)."""

    tau: np.ndarray        # (6,) commanded body wrench, N and N m
    tau_hat: np.ndarray    # (6,) the wrench the law holds against the disturbance, after this tick's update
    s: np.ndarray          # (6,) sliding variable (backstepping Eq. 2.14, smc, ismc)
    grad: np.ndarray       # (6,) (J M^-1)^T s, the adaptation direction and the fuzzy input (backstepping)
    gamma: np.ndarray      # (6,) adaptation rates used (constant, fuzzy)


class Controller:
    """A law with its state (estimates, integrators), for a loop that runs tick by tick (the runner)."""

    def __init__(self, model: Vehicle, settings: ControllerSettings):
        self.settings = settings
        self.model = model.packed()      # the packed model the law (and the prediction) use
        self._params = settings.vector
        self._args = settings.kernel_arguments()
        self.state = np.zeros(law_kernel.STATE_SIZE)

    def reset(self) -> None:
        """Back to the state of a new run (no estimate, empty integrators)."""
        self.state[:] = 0.0

    def step(self, eta: np.ndarray, nu: np.ndarray, reference: np.ndarray, dt: float) -> ControlOutput:
        """tau for the measured state against reference (18,), then the state advanced by dt seconds."""
        kind, table, scale = self._args
        tau, tau_hat, s, grad, gamma = (np.zeros(6) for _ in range(5))
        eta = np.asarray(eta, float)
        law_kernel.controller_step(kind, self.model, self._params, table, scale, eta, kernel.attitude_trig(eta),
                                   np.asarray(nu, float), np.asarray(reference, float), float(dt), self.state,
                                   tau, tau_hat, s, grad, gamma)
        return ControlOutput(tau, tau_hat, s, grad, gamma)
