"""Vehicle parameters: the YAML file (read and written), its validation, and the mass, added-mass and restoring
quantities."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property
from importlib import resources
from pathlib import Path
from typing import Annotated

import numpy as np
import yaml
from pydantic import Field, field_validator, model_validator

from rov_mav import config
from rov_mav.model import kernel
from rov_mav.model.frames import FRAMES, HEAVY, MAX_MOTORS, Frame, frame_named

MAX_VALUE = 1e6   # |any number| in a vehicle file (SI units): far beyond any ROV, and products stay finite
Real = Annotated[float, Field(ge=-MAX_VALUE, le=MAX_VALUE)]
Vec3 = Annotated[list[Real], Field(min_length=3, max_length=3)]
Vec6 = Annotated[list[Real], Field(min_length=6, max_length=6)]
Positive = Annotated[float, Field(gt=0, le=MAX_VALUE)]
NonNegative6 = Annotated[list[Annotated[float, Field(ge=0, le=MAX_VALUE)]], Field(min_length=6, max_length=6)]

DEFAULT_VEHICLE_FILE = "bluerov2_heavy.yaml"
FLOWN_THRUSTERS = 8      # the controller, allocation and simulator drive the Heavy's eight (`load_flown_vehicle`)


class _QuadraticSchema(config.StrictModel):
    max_thrust: Positive | Annotated[list[Positive], Field(min_length=1, max_length=MAX_MOTORS)]
    max_reverse: Positive | Annotated[list[Positive], Field(min_length=1, max_length=MAX_MOTORS)] | None = None
    dead_band: Annotated[list[float], Field(min_length=2, max_length=2)] = [1475.0, 1525.0]
    full_scale: Positive = 400.0

    @model_validator(mode="after")
    def _band(self) -> "_QuadraticSchema":
        low, high = self.dead_band
        if not 1500.0 - self.full_scale < low <= 1500.0 <= high < 1500.0 + self.full_scale:
            raise ValueError(f"dead_band must hold 1500 and lie within 1500 +- full_scale ({self.full_scale:g} us)")
        return self


class _CurveSchema(config.StrictModel):
    quadratic: _QuadraticSchema


class _ThrusterSchema(config.StrictModel):
    positions: Annotated[list[Vec3], Field(min_length=1, max_length=MAX_MOTORS)]
    directions: Annotated[list[Vec3], Field(min_length=1, max_length=MAX_MOTORS)]
    time_constant: Annotated[float, Field(ge=0, le=10.0)]
    thrust_scale: Annotated[list[Positive], Field(min_length=2, max_length=2)] = [1.0, 1.0]
    per_thruster_scale: Annotated[list[Positive], Field(min_length=1, max_length=MAX_MOTORS)] | None = None
    curve: _CurveSchema | None = None          # "t200" or absent: the Blue Robotics T200 data

    @field_validator("curve", mode="before")
    @classmethod
    def _t200(cls, curve):
        if curve is None or curve == "t200":
            return None
        if not isinstance(curve, dict):
            raise ValueError("must be t200 or {quadratic: {max_thrust: N, dead_band: [low, high], full_scale: us}}")
        return curve

    @field_validator("directions")
    @classmethod
    def _unit(cls, directions: list[list[float]]) -> list[list[float]]:
        for i, d in enumerate(directions):
            if abs(float(np.linalg.norm(d)) - 1.0) > 1e-3:
                raise ValueError(f"thruster {i + 1} direction is not a unit vector")
        return directions

    @model_validator(mode="after")
    def _one_entry_per_thruster(self) -> "_ThrusterSchema":
        n = len(self.positions)
        lists = {"directions": self.directions, "per_thruster_scale": self.per_thruster_scale}
        if self.curve is not None:
            lists |= {"curve.quadratic.max_thrust": self.curve.quadratic.max_thrust,
                      "curve.quadratic.max_reverse": self.curve.quadratic.max_reverse}
        for name, values in lists.items():
            if isinstance(values, list) and len(values) != n:
                raise ValueError(f"{name} lists {len(values)} thrusters, positions {n}")
        return self


class _VehicleSchema(config.StrictModel):
    name: str
    frame: str = HEAVY.label          # ArduSub's FRAME_CONFIG, by its label in lower case
    mass: Positive
    volume: Positive
    water_density: Positive
    gravity: Positive
    inertia: Annotated[list[Positive], Field(min_length=3, max_length=3)]
    inertia_products: Vec3
    center_of_gravity: Vec3
    center_of_buoyancy: Vec3
    added_mass: NonNegative6
    linear_damping: NonNegative6
    quadratic_damping: NonNegative6
    size: Annotated[list[Positive], Field(min_length=3, max_length=3)]
    thrusters: _ThrusterSchema

    @property
    def inertia_tensor(self) -> np.ndarray:
        """(3, 3) about the CG, from the moments and the products (Ixy, Iyz, Ixz)."""
        ixy, iyz, ixz = self.inertia_products
        ix, iy, iz = self.inertia
        return np.array([[ix, -ixy, -ixz], [-ixy, iy, -iyz], [-ixz, -iyz, iz]])

    @field_validator("frame")
    @classmethod
    def _known_frame(cls, name: str) -> str:
        try:
            frame_named(name)
        except KeyError:
            raise ValueError(f"unknown frame {name!r}: ArduSub's frames are "
                             + ", ".join(f.label for f in FRAMES.values())) from None
        return name

    @model_validator(mode="after")
    def _thrusters_of_the_frame(self) -> "_VehicleSchema":
        frame, count = frame_named(self.frame), len(self.thrusters.positions)
        if frame.motors != count:
            raise ValueError(f"frame: {frame.label} has {frame.motors} motors, thrusters lists {count}")
        return self

    @model_validator(mode="after")
    def _inertia_positive_definite(self) -> "_VehicleSchema":
        if np.linalg.eigvalsh(self.inertia_tensor).min() <= 0:
            raise ValueError("inertia: the inertia tensor is not positive definite")
        return self


@dataclass(frozen=True)
class QuadraticCurve:
    """A thruster force law F = k sign(o) o^2, o = (pwm - 1500) / full_scale, zero inside the dead band (ArduPilot's
    SITL submarine; `rov_mav.model.thrusters.ThrusterMap.quadratic` turns it into a map). k per thruster and
    direction."""

    max_forward: np.ndarray          # (n,) N at 1500 + full_scale, per thruster
    max_reverse: np.ndarray          # (n,) N (magnitudes) at 1500 - full_scale
    dead_band: tuple[float, float]   # us, force 0 from low to high inclusive
    full_scale: float                # us

    def document(self) -> dict:
        """The `thrusters.curve` mapping of a vehicle file."""
        return {"quadratic": {"max_thrust": self.max_forward.tolist(), "max_reverse": self.max_reverse.tolist(),
                              "dead_band": list(self.dead_band), "full_scale": self.full_scale}}


@dataclass(frozen=True)
class Vehicle:
    """A rigid vehicle in water: everything the 6-DOF model (Eq. 2.7, Appendix I) needs, in SI units."""

    name: str
    mass: float
    volume: float
    water_density: float
    gravity: float
    inertia_tensor: np.ndarray        # (3, 3) about the CG
    center_of_gravity: np.ndarray     # (3,)
    center_of_buoyancy: np.ndarray    # (3,)
    added_mass: np.ndarray            # (6,) positive magnitudes
    linear_damping: np.ndarray        # (6,)
    quadratic_damping: np.ndarray     # (6,)
    size: np.ndarray                  # (3,) length, width, height
    thruster_positions: np.ndarray    # (n, 3): n = frame.motors, motor k is thruster k
    thruster_directions: np.ndarray   # (n, 3)
    thruster_time_constant: float
    thrust_scale: np.ndarray = field(default_factory=lambda: np.ones(2))   # (2,) forward, reverse: x the curve
    per_thruster_scale: np.ndarray = field(default_factory=lambda: np.ones(8))   # (n,) each thruster's, x the above
    thruster_curve: QuadraticCurve | None = None   # None: the Blue Robotics T200 data at the battery voltage
    frame: Frame = HEAVY             # ArduSub's frame whose motors 1..n are thrusters T1..Tn

    @property
    def weight(self) -> float:
        """W = m g."""
        return self.mass * self.gravity

    @property
    def buoyancy(self) -> float:
        """B = rho g V (ERRATA 6)."""
        return self.water_density * self.gravity * self.volume

    @cached_property
    def rigid_body_mass_matrix(self) -> np.ndarray:
        """M_RB of Appendix I about the body origin, with the inertia products: positive definite for any r_g."""
        m = self.mass
        xg, yg, zg = self.center_of_gravity
        mrb = np.zeros((6, 6))
        mrb[:3, :3] = m * np.eye(3)
        s = m * np.array([[0.0, -zg, yg], [zg, 0.0, -xg], [-yg, xg, 0.0]])
        mrb[:3, 3:] = -s
        mrb[3:, :3] = s
        mrb[3:, 3:] = self.inertia_tensor - s @ s / m   # about the origin: I_o = I_g - m S(r_g)^2 (parallel axes)
        return mrb

    @cached_property
    def mass_matrix(self) -> np.ndarray:
        """M = M_RB + M_A, symmetric positive definite (Eq. 2.8)."""
        return self.rigid_body_mass_matrix + np.diag(self.added_mass)

    def packed(self) -> np.ndarray:
        """The flat float64 vector the compiled kernel reads (layout in `rov_mav.model.kernel`)."""
        out = np.zeros(kernel.P_SIZE)
        out[kernel.P_M:kernel.P_M + 36] = self.mass_matrix.ravel()
        out[kernel.P_MINV:kernel.P_MINV + 36] = np.linalg.inv(self.mass_matrix).ravel()
        out[kernel.P_DLIN:kernel.P_DLIN + 6] = self.linear_damping
        out[kernel.P_DQUAD:kernel.P_DQUAD + 6] = self.quadratic_damping
        out[kernel.P_W] = self.weight
        out[kernel.P_B] = self.buoyancy
        out[kernel.P_RG:kernel.P_RG + 3] = self.center_of_gravity
        out[kernel.P_RB:kernel.P_RB + 3] = self.center_of_buoyancy
        return out

    def scaled(self, factor: float) -> "Vehicle":
        """The same vehicle with mass, inertia, added mass and damping multiplied by `factor` (model-error studies).

        Volume scales too, so the buoyancy balance is kept."""
        return replace(
            self,
            name=f"{self.name} x{factor:g}",
            mass=self.mass * factor,
            volume=self.volume * factor,
            inertia_tensor=self.inertia_tensor * factor,
            added_mass=self.added_mass * factor,
            linear_damping=self.linear_damping * factor,
            quadratic_damping=self.quadratic_damping * factor,
        )

    def document(self) -> dict:
        """The vehicle as the mapping a vehicle file holds (`load_vehicle` reads it back to an equal Vehicle)."""
        i = self.inertia_tensor

        def floats(a) -> list:
            return np.asarray(a, dtype=float).tolist()

        return {
            "name": self.name,
            "frame": self.frame.label,
            "mass": float(self.mass),
            "volume": float(self.volume),
            "water_density": float(self.water_density),
            "gravity": float(self.gravity),
            "inertia": floats(np.diag(i)),
            "inertia_products": [float(-i[0, 1]) + 0.0, float(-i[1, 2]) + 0.0, float(-i[0, 2]) + 0.0],
            "center_of_gravity": floats(self.center_of_gravity),
            "center_of_buoyancy": floats(self.center_of_buoyancy),
            "added_mass": floats(self.added_mass),
            "linear_damping": floats(self.linear_damping),
            "quadratic_damping": floats(self.quadratic_damping),
            "size": floats(self.size),
            "thrusters": {
                "positions": floats(self.thruster_positions),
                "directions": floats(self.thruster_directions),
                "time_constant": float(self.thruster_time_constant),
                "thrust_scale": floats(self.thrust_scale),
                "per_thruster_scale": floats(self.per_thruster_scale),
            } | ({} if self.thruster_curve is None else {"curve": self.thruster_curve.document()}),
        }


def default_vehicle_path() -> Path:
    """The shipped BlueROV2 Heavy parameter file."""
    return Path(str(resources.files("rov_mav") / "data" / DEFAULT_VEHICLE_FILE))


def load_vehicle(path: str | Path | None = None) -> Vehicle:
    """Load and validate a vehicle file (default: the shipped BlueROV2 Heavy); ConfigError on any bad entry."""
    path = Path(path) if path is not None else default_vehicle_path()
    s = config.load(_VehicleSchema, path)
    return Vehicle(
        name=s.name,
        mass=s.mass,
        volume=s.volume,
        water_density=s.water_density,
        gravity=s.gravity,
        inertia_tensor=s.inertia_tensor,
        center_of_gravity=np.array(s.center_of_gravity, dtype=float),
        center_of_buoyancy=np.array(s.center_of_buoyancy, dtype=float),
        added_mass=np.array(s.added_mass, dtype=float),
        linear_damping=np.array(s.linear_damping, dtype=float),
        quadratic_damping=np.array(s.quadratic_damping, dtype=float),
        size=np.array(s.size, dtype=float),
        thruster_positions=np.array(s.thrusters.positions, dtype=float),
        thruster_directions=np.array(s.thrusters.directions, dtype=float),
        thruster_time_constant=s.thrusters.time_constant,
        thrust_scale=np.array(s.thrusters.thrust_scale, dtype=float),
        per_thruster_scale=np.array(s.thrusters.per_thruster_scale or [1.0] * len(s.thrusters.positions), float),
        thruster_curve=_curve(s.thrusters.curve, len(s.thrusters.positions)),
        frame=frame_named(s.frame),
    )


def load_flown_vehicle(path: str | Path | None = None) -> Vehicle:
    """A vehicle file for what flies or simulates it (run, simulate, tune, bench, the built-in vehicle): their
    controller, allocation and simulator drive eight thrusters, so a frame of fewer (the standard BlueROV2's six) is
    refused here, in one line (ConfigError); such a file is a prior for identify and analyze."""
    vehicle = load_vehicle(path)
    if len(vehicle.thruster_positions) != FLOWN_THRUSTERS:
        raise config.ConfigError(
            f"{path or default_vehicle_path()}: {vehicle.name} is {vehicle.frame.describe()}: rov-mav flies and "
            f"simulates {FLOWN_THRUSTERS}-thruster vehicles only (this file is a prior for identify and analyze)")
    return vehicle


def _curve(spec: _CurveSchema | None, thrusters: int) -> QuadraticCurve | None:
    if spec is None:
        return None
    q = spec.quadratic
    forward = np.broadcast_to(np.asarray(q.max_thrust, dtype=float), (thrusters,)).copy()
    reverse = forward if q.max_reverse is None else \
        np.broadcast_to(np.asarray(q.max_reverse, float), (thrusters,)).copy()
    return QuadraticCurve(forward, reverse, (float(q.dead_band[0]), float(q.dead_band[1])), float(q.full_scale))


def save_vehicle(vehicle: Vehicle, path: str | Path, header: str = "") -> None:
    """Write `vehicle` as a vehicle file, `header` as leading comment lines; `load_vehicle` reads it back."""
    path = Path(path)
    comments = "".join(f"# {line}\n" if line else "#\n" for line in header.splitlines())
    text = comments + yaml.safe_dump(vehicle.document(), sort_keys=False, default_flow_style=None, width=120)
    partial = path.with_name(path.name + ".partial")
    try:
        partial.write_text(text)
    except OSError as exc:
        raise OSError(exc.errno, exc.strerror, str(path)) from None
    partial.replace(path)          # whole or not at all
