"""The bottom and the ice ceiling the built-in vehicle meets: a surface's depth at every north/east point.

A surface's depth (m, positive down) at a point is its depth at the origin, less `slope` times the distance along
`heading` (a positive slope rises along it), less the rise of every step passed, or, with a `profile`, that profile's
depth at the distance along `heading` (linear between its points, held beyond its ends), plus the relief: a sum of
plane waves of random directions and phases (seeded) whose wavelengths spread over [wavelength / 2, 2 wavelength],
scaled to `relief` m RMS. The same shape serves a seafloor (the water above it) and an ice ceiling (the water below
it). `rov_mav.review` rebuilds a profile from a real log's depth plus echo-sounder range.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Annotated

import numpy as np
from pydantic import Field, field_validator

from rov_mav import config
from rov_mav.units import Angle

RELIEF_WAVES = 24                 # plane waves summed for the relief (chosen: isotropic enough, cheap per ray)
Slope = Annotated[float, Field(ge=-1, le=1)]       # rise per m: beyond 45 degrees no sounder sees a bottom


class SurfaceSchema(config.StrictModel):
    """A `seafloor:` or `ice:` block of an environment."""

    depth: Annotated[float, Field(ge=0, le=11000)] = 10.0   # m at the origin (without a profile)
    slope: Slope = 0.0                                     # rise per m along `heading`
    heading: Angle = 0.0                                   # the slope's, the steps' and the profile's direction
    steps: list[Annotated[list[float], Field(min_length=2, max_length=2)]] = []   # [distance m, rise m] each
    profile: list[Annotated[list[float], Field(min_length=2, max_length=2)]] = []  # [distance m, depth m] each
    relief: Annotated[float, Field(ge=0, le=10)] = 0.0     # m RMS
    wavelength: Annotated[float, Field(gt=0, le=1000)] = 3.0   # m: the relief's typical wavelength
    seed: Annotated[int, Field(ge=0)] = 0

    @field_validator("profile")
    @classmethod
    def _profile_increases(cls, value):
        distances = [p[0] for p in value]
        if value and (len(value) < 2 or any(b <= a for a, b in zip(distances, distances[1:]))):
            raise ValueError("a profile needs two or more [distance, depth] points, distances increasing")
        if any(p[1] < 0 for p in value):
            raise ValueError("a profile's depths are m below the surface (>= 0)")
        return value


@dataclass(frozen=True)
class Surface:
    """A bottom or an ice ceiling: `depth_at(north, east)` m, positive down, for points or arrays of them."""

    depth: float = 10.0
    slope: float = 0.0
    heading: float = 0.0
    steps: tuple[tuple[float, float], ...] = ()
    profile: tuple[tuple[float, float], ...] = ()
    relief: float = 0.0
    wavelength: float = 3.0
    seed: int = 0
    _waves: np.ndarray = field(init=False, repr=False, compare=False)
    _profile: np.ndarray = field(init=False, repr=False, compare=False)     # (K, 2) of `profile`, once

    def __post_init__(self):
        rng = np.random.default_rng(np.random.SeedSequence([self.seed, 40]))
        direction = rng.uniform(0.0, 2 * np.pi, RELIEF_WAVES)
        wavenumber = 2 * np.pi / (self.wavelength * 2.0 ** rng.uniform(-1.0, 1.0, RELIEF_WAVES))
        phase = rng.uniform(0.0, 2 * np.pi, RELIEF_WAVES)
        amplitude = np.full(RELIEF_WAVES, self.relief * np.sqrt(2.0 / RELIEF_WAVES))   # RMS of the sum: relief
        waves = np.stack([wavenumber * np.cos(direction), wavenumber * np.sin(direction), phase, amplitude])
        object.__setattr__(self, "_waves", waves)
        object.__setattr__(self, "_profile", np.asarray(self.profile, dtype=float).reshape(-1, 2))

    @classmethod
    def from_schema(cls, s: SurfaceSchema) -> "Surface":
        return cls(depth=s.depth, slope=s.slope, heading=float(s.heading), steps=tuple(map(tuple, s.steps)),
                   profile=tuple(map(tuple, s.profile)), relief=s.relief, wavelength=s.wavelength, seed=s.seed)

    def along(self, north, east):
        """m along `heading` from the origin."""
        return np.cos(self.heading) * np.asarray(north, dtype=float) + np.sin(self.heading) * np.asarray(
            east, dtype=float)

    def depth_at(self, north, east):
        """The surface's depth (m, positive down) at north, east (m from the origin; numbers or arrays)."""
        s = self.along(north, east)
        if self.profile:
            base = np.interp(s, self._profile[:, 0], self._profile[:, 1])
        else:
            base = self.depth - self.slope * s
        for at, rise in self.steps:
            base = base - rise * (s >= at)
        if self.relief > 0:
            kx, ky, phase, amplitude = self._waves
            n = np.asarray(north, dtype=float)[..., None]
            e = np.asarray(east, dtype=float)[..., None]
            base = base + np.sum(amplitude * np.cos(kx * n + ky * e + phase), axis=-1)
        return base if np.ndim(base) else float(base)


def parse_surface(value, source: str) -> Surface:
    """A `seafloor:` or `ice:` mapping (ConfigError, one line, naming `source`)."""
    return Surface.from_schema(config.parse(SurfaceSchema, value, source))
