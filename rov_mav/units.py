"""Angles (wrapping; in configuration files radians by default, or '90 deg', '1.57 rad'), durations written with their
unit ('50ms', '2s') in fault descriptions, and latitude and longitude as metres on ArduPilot's flat earth."""

from __future__ import annotations

import math
import re
from typing import Annotated, Any

import numpy as np
from pydantic import BeforeValidator


EARTH_RADIUS = 6378137.0     # m: ArduPilot's flat-earth conversion (`Location::get_distance_NE`)


def north_east(lat: float, lon: float, origin: tuple[float, float, float]) -> tuple[float, float]:
    """m north and east of the origin (lat deg, lon deg, alt m) of a point at lat, lon deg, on the flat earth."""
    lat0, lon0, _ = origin
    return (math.radians(lat - lat0) * EARTH_RADIUS,
            math.radians(lon - lon0) * EARTH_RADIUS * math.cos(math.radians(lat0)))


def lat_lon(north: float, east: float, origin: tuple[float, float, float]) -> tuple[float, float]:
    """(lat, lon) deg of the point north, east m of the origin on the same flat earth (`north_east`'s inverse)."""
    lat0, lon0, _ = origin
    return (lat0 + math.degrees(north / EARTH_RADIUS),
            lon0 + math.degrees(east / (EARTH_RADIUS * math.cos(math.radians(lat0)))))


def wrap_angle(angle):
    """Wrap radians to [-pi, pi); scalars stay floats, arrays stay arrays (the compiled kernel has its own)."""
    if isinstance(angle, (float, int)):         # a scalar (numpy's float64 too), without numpy's call
        return (float(angle) + math.pi) % (2 * math.pi) - math.pi
    wrapped = (np.asarray(angle, dtype=float) + np.pi) % (2 * np.pi) - np.pi
    return float(wrapped) if wrapped.ndim == 0 else wrapped


def parse_angle(value: Any) -> float:
    """Return radians from a number (radians) or a string 'VALUE deg' / 'VALUE rad'.

    A bare number beyond 2 pi is refused: it is almost certainly degrees written without the unit."""
    if isinstance(value, bool):
        raise ValueError("expected an angle, e.g. 1.57 (radians) or '90 deg'")
    if isinstance(value, (int, float)):
        if abs(value) > 2 * math.pi:
            raise ValueError(f"{value} is more than 2 pi radians: degrees need a unit, e.g. '{value} deg'")
        return float(value)
    if isinstance(value, str):
        parts = value.split()
        if len(parts) == 2 and parts[1] in ("deg", "rad"):
            try:
                number = float(parts[0])
            except ValueError:
                raise ValueError(f"'{value}' is not an angle like '90 deg' or '1.57 rad'") from None
            return math.radians(number) if parts[1] == "deg" else number
    raise ValueError(f"'{value}' is not an angle like 1.57 (radians), '90 deg' or '1.57 rad'")


Angle = Annotated[float, BeforeValidator(parse_angle)]


_DURATION = re.compile(r"^\s*([-+0-9.eE]+|nan|inf)\s*(ms|s)\s*$", re.IGNORECASE)


def parse_duration(text: str) -> float | None:
    """Seconds from '50ms' or '2s' (the unit required); None unless it is a finite time of 0 or more."""
    match = _DURATION.match(text)
    try:
        value = float(match.group(1)) * (1e-3 if match.group(2).lower() == "ms" else 1.0) if match else math.nan
    except ValueError:
        return None
    return value if math.isfinite(value) and value >= 0 else None
