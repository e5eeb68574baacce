"""Controller settings (gains, adaptation) and the stateful controller the runner steps once per tick.

The law and the adaptation themselves are in `rov_mav.control.law_kernel` (compiled, shared with simulate and tune).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from importlib import resources
from pathlib import Path
from typing import Annotated

import numpy as np
from pydantic import Field

from rov_mav import config
from rov_mav.control import law_kernel
from rov_mav.control.fuzzy import FuzzySchedule, load_fuzzy
from rov_mav.model.vehicle import Vehicle

PositiveVec6 = Annotated[list[Annotated[float, Field(gt=0)]], Field(min_length=6, max_length=6)]

SCHEDULES = {"baseline": law_kernel.SCHEDULE_NONE, "constant": law_kernel.SCHEDULE_CONSTANT, "fuzzy": law_kernel.SCHEDULE_FUZZY}


class _ControllerSchema(config.StrictModel):
    k1: PositiveVec6 | None = None
    k2: PositiveVec6 | None = None
    constant_gamma: PositiveVec6 | None = None
    d_max: PositiveVec6 | None = None


@dataclass(frozen=True)
class ControllerSettings:
    """Everything that defines the law and its adaptation, apart from the vehicle model."""

    kind: str                 # baseline | constant | fuzzy
    k1: np.ndarray            # (6,) Eq. 2.14
    k2: np.ndarray            # (6,) Eq. 2.17
    constant_gamma: np.ndarray
    d_max: np.ndarray
    fuzzy: FuzzySchedule

    @property
    def gains(self) -> np.ndarray:
        """[k1 | k2], (12,): the vector PSO tunes."""
        return np.concatenate([self.k1, self.k2])

    def with_gains(self, gains: np.ndarray) -> "ControllerSettings":
        return replace(self, k1=np.asarray(gains[:6], float), k2=np.asarray(gains[6:], float))

    def kernel_arguments(self) -> tuple:
        """(schedule, constant_gamma, table, table_xmax, d_max) as the kernel takes them."""
        return (SCHEDULES[self.kind], self.constant_gamma, self.fuzzy.table, self.fuzzy.table_xmax, self.d_max)


def default_controller_path() -> Path:
    return Path(str(resources.files("rov_mav") / "data" / "controller.yaml"))


def load_settings(kind: str = "fuzzy", gains_file: str | Path | None = None,
                  fuzzy_file: str | Path | None = None, k1: list[float] | None = None,
                  k2: list[float] | None = None) -> ControllerSettings:
    """Shipped defaults, overridden by a gains file, overridden by explicit k1/k2 (e.g. from the command line)."""
    if kind not in SCHEDULES:
        raise config.ConfigError(f"controller: unknown kind '{kind}' (choose from {', '.join(SCHEDULES)})")
    merged = config.load(_ControllerSchema, default_controller_path()).model_dump()
    if gains_file is not None:
        override = config.load(_ControllerSchema, gains_file).model_dump(exclude_none=True)
        merged.update(override)
    for name, value in (("k1", k1), ("k2", k2)):
        if value is not None:
            config.parse(_ControllerSchema, {name: [float(v) for v in value]}, f"--{name}")
            merged[name] = list(value)
    return ControllerSettings(
        kind=kind,
        k1=np.array(merged["k1"], float),
        k2=np.array(merged["k2"], float),
        constant_gamma=np.array(merged["constant_gamma"], float),
        d_max=np.array(merged["d_max"], float),
        fuzzy=load_fuzzy(fuzzy_file),
    )


@dataclass(frozen=True)
class ControlOutput:
    """One tick of the controller: the wrench and the internals worth logging."""

    tau: np.ndarray        # (6,) commanded body wrench, N and N m
    tau_hat: np.ndarray    # (6,) disturbance estimate after this tick's update
    s: np.ndarray          # (6,) sliding variable, Eq. 2.14
    grad: np.ndarray       # (6,) (J M^-1)^T s, the adaptation direction and the fuzzy input
    gamma: np.ndarray      # (6,) adaptation rates used


class Controller:
    """The law with its disturbance estimate as state, for a loop that runs tick by tick (the runner)."""

    def __init__(self, model: Vehicle, settings: ControllerSettings):
        self.settings = settings
        self._model = model.packed()
        self._args = settings.kernel_arguments()
        self.tau_hat = np.zeros(6)

    def step(self, eta: np.ndarray, nu: np.ndarray, reference: np.ndarray, dt: float) -> ControlOutput:
        """tau for the measured state against reference (18,), then the estimate advanced by dt seconds."""
        schedule, gamma_const, table, xmax, d_max = self._args
        tau, s, grad, gamma = np.zeros(6), np.zeros(6), np.zeros(6), np.zeros(6)
        law_kernel.controller_step(self._model, self.settings.k1, self.settings.k2, schedule, gamma_const, table, xmax,
                               d_max, np.asarray(eta, float), np.asarray(nu, float), np.asarray(reference, float),
                               float(dt), self.tau_hat, tau, s, grad, gamma)
        return ControlOutput(tau, self.tau_hat.copy(), s, grad, gamma)
