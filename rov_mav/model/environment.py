"""The simulated water: constant and periodic disturbance, a slow current, sensor noise, the bottom and an ice
ceiling (simulation only)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated

import numpy as np
from pydantic import Field, field_validator, model_validator

from rov_mav import config
from rov_mav.model import kernel
from rov_mav.model.navigation import Navigation, NavigationError, parse_navigation
from rov_mav.model.seafloor import Surface, SurfaceSchema
from rov_mav.model.vehicle_faults import (
    OFFLINE_VOLTAGE,
    VehicleFaultError,
    VehicleFaults,
    items_of,
    parse_vehicle_faults,
    wrench_map,
)

Vec3 = Annotated[list[float], Field(min_length=3, max_length=3)]
Vec6 = Annotated[list[float], Field(min_length=6, max_length=6)]
NonNegative = Annotated[float, Field(ge=0)]


class NoiseSchema(config.StrictModel):
    position: NonNegative = 0.0   # m, std dev on x, y, z
    attitude: NonNegative = 0.0   # rad, on phi, theta, psi
    velocity: NonNegative = 0.0   # m/s, on u, v, w
    rate: NonNegative = 0.0       # rad/s, on p, q, r


class TelemetrySchema(config.StrictModel):
    """How the controller sees the state offline: sampled at `rate` and `delay` late (a 5-10 Hz MAVLink stream), and
    whether it predicts that late state forward to now through its model and the wrenches it commanded since (as
    `rov-mav run` does unless --predict off)."""

    rate: Annotated[float, Field(ge=0, le=1000)] = 0.0   # Hz; 0 = every control tick
    delay: Annotated[float, Field(ge=0, le=5)] = 0.0     # s, from the sample to the controller
    predict: bool = True


class EnvironmentSchema(config.StrictModel):
    disturbance: Vec6 = [0.0] * 6             # tau_d, body frame, N and N m (Eq. 2.7)
    disturbance_amplitude: Vec6 = [0.0] * 6   # amplitude of a sinusoid added to tau_d
    disturbance_period: NonNegative = 0.0     # s; 0 = no sinusoid
    current: Vec3 = [0.0] * 3                 # NED water velocity, m/s
    noise: NoiseSchema = NoiseSchema()
    telemetry: TelemetrySchema = TelemetrySchema()   # offline only: `run` sees the real link's stream
    vehicle_faults: str | list[str] | None = None      # `rov_mav.model.vehicle_faults`' grammar
    navigation: str | dict | None = None               # a preset or a block (`rov_mav.model.navigation`)
    seafloor: SurfaceSchema | None = None              # the bottom (`rov_mav.model.seafloor`); none: no bottom
    ice: SurfaceSchema | None = None                   # an ice ceiling above the vehicle; none: open water

    @field_validator("navigation")
    @classmethod
    def _navigation_parses(cls, value):
        if value is not None:
            try:
                parse_navigation(value, "environment: navigation")
            except NavigationError as exc:
                raise ValueError(str(exc).removeprefix("environment: navigation: ")) from None
        return value

    @field_validator("vehicle_faults")
    @classmethod
    def _faults_parse(cls, value):
        if value is not None:
            try:
                parse_vehicle_faults(items_of(value, "environment"))
            except VehicleFaultError as exc:
                raise ValueError(str(exc)) from None
        return value

    @model_validator(mode="after")
    def _sinusoid_needs_a_period(self) -> "EnvironmentSchema":
        if any(self.disturbance_amplitude) and self.disturbance_period == 0:
            raise ValueError("disturbance_amplitude needs a disturbance_period > 0 (s)")
        return self


class _EnvironmentFile(config.StrictModel):
    environment: EnvironmentSchema


@dataclass(frozen=True)
class Environment:
    """What the simulated vehicle meets and the controller does not know."""

    disturbance: np.ndarray = field(default_factory=lambda: np.zeros(6))
    disturbance_amplitude: np.ndarray = field(default_factory=lambda: np.zeros(6))
    disturbance_period: float = 0.0
    current: np.ndarray = field(default_factory=lambda: np.zeros(3))
    noise: np.ndarray = field(default_factory=lambda: np.zeros(4))   # position, attitude, velocity, rate
    telemetry: np.ndarray = field(default_factory=lambda: np.zeros(2))   # sample period (s, 0 = every tick), delay (s)
    predict: bool = True        # the controller predicts its late measurement forward
    vehicle_faults: VehicleFaults = VehicleFaults()   # what fails on the vehicle, and when
    navigation: Navigation | None = None  # the built-in vehicle's navigation (None: ideal); offline, its errors
    # along the mission as a run meets them (`rov_mav.commands.common.navigation_errors`)
    seafloor: Surface | None = None       # the bottom (None: too deep to matter, no sounder sees it)
    ice: Surface | None = None            # an ice ceiling (None: open water up to the surface)

    @classmethod
    def from_schema(cls, s: EnvironmentSchema) -> "Environment":
        return cls(
            disturbance=np.array(s.disturbance, dtype=float),
            disturbance_amplitude=np.array(s.disturbance_amplitude, dtype=float),
            disturbance_period=s.disturbance_period,
            current=np.array(s.current, dtype=float),
            noise=np.array([s.noise.position, s.noise.attitude, s.noise.velocity, s.noise.rate]),
            telemetry=np.array([1.0 / s.telemetry.rate if s.telemetry.rate > 0 else 0.0, s.telemetry.delay]),
            predict=s.telemetry.predict,
            vehicle_faults=(parse_vehicle_faults(items_of(s.vehicle_faults, "environment"))
                            if s.vehicle_faults is not None else VehicleFaults()),
            navigation=(parse_navigation(s.navigation, "environment") if s.navigation is not None else None),
            seafloor=Surface.from_schema(s.seafloor) if s.seafloor is not None else None,
            ice=Surface.from_schema(s.ice) if s.ice is not None else None,
        )

    @property
    def constant_disturbance(self) -> np.ndarray | None:
        """tau_d when it is constant (what an estimate should converge to), else None."""
        if self.disturbance_period > 0 and np.any(self.disturbance_amplitude):
            return None
        return self.disturbance

    def packed(self, vehicle=None) -> np.ndarray:
        """The flat vector the compiled kernel reads (layout in `rov_mav.model.kernel`). With the plant's `vehicle`
        (the offline loop's), its thruster faults are packed too (ConfigError for a fault only the built-in vehicle's
        autopilot can meet); without, none: the bridge applies them to its own thrusters."""
        out = np.zeros(kernel.E_SIZE)
        out[kernel.E_FAULT_AT] = np.inf
        out[kernel.E_FAULT_MAP:kernel.E_FAULT_MAP + 36] = np.eye(6).ravel()
        if vehicle is not None and self.vehicle_faults:
            out[kernel.E_FAULT_AT:kernel.E_FAULT_PUSH + 6] = self._offline_faults(vehicle)
        out[kernel.E_DIST:kernel.E_DIST + 6] = self.disturbance
        out[kernel.E_AMP:kernel.E_AMP + 6] = self.disturbance_amplitude
        out[kernel.E_PERIOD] = self.disturbance_period
        out[kernel.E_CURRENT:kernel.E_CURRENT + 3] = self.current
        out[kernel.E_NOISE:kernel.E_NOISE + 4] = self.noise
        out[kernel.E_SAMPLE_PERIOD] = self.telemetry[0]
        out[kernel.E_SAMPLE_DELAY] = self.telemetry[1]
        out[kernel.E_PREDICT] = float(self.predict)
        return out


    def _offline_faults(self, vehicle) -> np.ndarray:
        from rov_mav.model.thrusters import allocation_matrix, thruster_curve

        faults = self.vehicle_faults
        if faults.autopilot_faults:
            raise config.ConfigError(f"environment: vehicle_faults: {', '.join(faults.autopilot_faults)}: only the "
                                     "built-in vehicle's autopilot meets these (rov-mav run, rov-mav sim-bridge); "
                                     "offline runs take thruster faults only")
        curve = thruster_curve(vehicle)
        try:
            at, matrix, push = wrench_map(faults, allocation_matrix(vehicle.thruster_positions,
                                                                    vehicle.thruster_directions),
                                          lambda pwm: curve.thrust(pwm, OFFLINE_VOLTAGE))
        except VehicleFaultError as exc:
            raise config.ConfigError(f"environment: vehicle_faults: {exc}") from None
        return np.r_[at, matrix.ravel(), push]


def load_environment(path: str | Path) -> Environment:
    """An environment from a file holding an `environment:` block (a mission file, or just that block)."""
    data = config.read_yaml(path)
    if "environment" not in data:
        raise config.ConfigError(f"{path}: environment: missing")
    block = config.parse(_EnvironmentFile, {"environment": data["environment"]}, path)
    return Environment.from_schema(block.environment)
