"""Missions: a YAML path (goto, hold, line, excite segments) turned into a smooth reference eta_d(t), eta_dot_d,
eta_ddot_d.

Every segment starts and ends with zero velocity and acceleration unless it is a line told not to ramp, so
eta_d, eta_dot_d and eta_ddot_d are continuous across segment boundaries (stop-and-turn corners). Roll and pitch
references are zero, except during an excite segment on roll or pitch. Positions are NED metres; headings radians
(or strings with 'deg'/'rad'). An excite segment holds the pose and adds a multisine or chirp on one body axis
(`rov_mav.mission.excitation`): the closed-loop excitation `rov-mav identify` fits a model to.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
from pydantic import AfterValidator, Field, model_validator

from rov_mav import config
from rov_mav.mission.excitation import AXES, SIGNALS, Excitation, excitation
from rov_mav.mission.terrain import MIN_HEIGHT
from rov_mav.model.environment import Environment, EnvironmentSchema
from rov_mav.units import Angle, parse_angle, wrap_angle

MAX_DURATION = 24 * 3600.0  # s: longer than any dive; long soak runs fit
MAX_SAMPLES = 1_440_000     # reference samples built at once: 4 h at 100 Hz (an offline run holds every step)
MAX_RANGE = 10_000.0        # m: |coordinate| of a start or waypoint
MAX_SPEED = 10.0            # m/s: far above a BlueROV2 Heavy's ~1.5 m/s
MIN_SEGMENT = 0.01          # s: the shortest hold or line (smooth ramps need a few control periods anyway)

Coordinate = Annotated[float, Field(ge=-MAX_RANGE, le=MAX_RANGE)]
Vec3 = Annotated[list[Coordinate], Field(min_length=3, max_length=3)]
Waypoint = Annotated[list[Coordinate], Field(min_length=2, max_length=3)]   # [north, east(, depth)]
Velocity = Annotated[list[Annotated[float, Field(ge=-MAX_SPEED, le=MAX_SPEED)]], Field(min_length=3, max_length=3)]
Positive = Annotated[float, Field(gt=0)]
Speed = Annotated[float, Field(gt=0, le=MAX_SPEED)]
Seconds = Annotated[float, Field(ge=MIN_SEGMENT, le=MAX_DURATION)]


def _folder_name(name: str) -> str:
    """A mission's name names its output folders (out/run-NAME): one plain path component."""
    if not 0 < len(name) <= 64 or name.startswith(".") or any(c in "/\\" or not c.isprintable() for c in name):
        raise ValueError("must be usable as a folder name: 1 to 64 printable characters, no '/' or '\\', "
                         "not starting with '.'")
    return name


Name = Annotated[str, AfterValidator(_folder_name)]

REFERENCE_COLUMNS = 18   # eta_d (6), eta_dot_d (6), eta_ddot_d (6)
SEGMENT_KINDS = ("goto", "hold", "line", "excite")
TRANSLATIONS = ("surge", "sway", "heave")


class _StartSchema(config.StrictModel):
    position: Vec3
    heading: Angle = 0.0


Height = Annotated[float, Field(ge=MIN_HEIGHT, le=100.0)]


class _SegmentSchema(config.StrictModel):
    goto: Waypoint | None = None    # NED waypoint, m (north and east alone with an altitude or a standoff)
    altitude: Height | None = None  # m above the bottom, held along a goto or hold (`rov_mav.mission.terrain`)
    standoff: Height | None = None  # m below an ice ceiling, the same way
    hold: Seconds | None = None     # s
    line: Velocity | None = None    # constant NED velocity, m/s
    speed: Speed | None = None      # m/s, cruise speed of a goto
    duration: Seconds | None = None  # s, of a line
    heading: Angle | None = None    # heading to reach by the end of a goto or hold
    ramp_up: bool = True            # line only: false starts at full velocity (the report's Eq. 3.1)
    excite: Literal[AXES] | None = None          # body axis to excite around the held pose
    signal: Literal[SIGNALS] = "multisine"       # excite only
    amplitude: float | str | None = None   # excite only: peak offset, m (surge, sway, heave) or an angle (the rest)
    band: Annotated[list[Positive], Field(min_length=2, max_length=2)] | None = None   # excite only: Hz, low, high

    @model_validator(mode="after")
    def _one_kind(self) -> "_SegmentSchema":
        kinds = [k for k in SEGMENT_KINDS if getattr(self, k) is not None]
        if kinds == ["goto", "excite"]:
            return self._check_moving_excite()
        if len(kinds) != 1:
            raise ValueError("each path entry needs exactly one of " + ", ".join(SEGMENT_KINDS)
                             + " (or an excite on a goto)")
        kind = kinds[0]
        if self.altitude is not None and self.standoff is not None:
            raise ValueError("a leg holds an altitude (above the bottom) or a standoff (below the ice), not both")
        if (self.altitude is not None or self.standoff is not None) and kind not in ("goto", "hold"):
            raise ValueError(f"altitude and standoff apply to goto and hold, not {kind}")
        if kind == "goto" and len(self.goto) == 2 and self.altitude is None and self.standoff is None:
            raise ValueError("a goto needs [north, east, depth], or [north, east] with an altitude or a standoff")
        if kind == "excite":
            return self._check_excite()
        if self.amplitude is not None or self.band is not None:
            raise ValueError(f"amplitude and band apply to excite, not {kind}")
        if kind == "goto" and self.speed is None:
            raise ValueError("a goto needs a speed (m/s)")
        if kind != "goto" and self.speed is not None:
            raise ValueError(f"speed applies to goto, not {kind}")
        if kind == "line" and self.duration is None:
            raise ValueError("a line needs a duration (s)")
        if kind not in ("line", "excite") and self.duration is not None:
            raise ValueError(f"duration applies to line, not {kind} (a hold's value is its duration)")
        if kind == "line" and self.heading is not None:
            raise ValueError("a line keeps the current heading; turn in a hold before it")
        if kind == "line" and math.hypot(*self.line) == 0:
            raise ValueError("a line needs a non-zero velocity")
        return self

    def _check_moving_excite(self) -> "_SegmentSchema":
        """An excite on a goto: the multisine rides on the move, over the goto's duration (couplings between a
        translation and a rotation: the Coriolis forces of pitching while surging, rolling while swaying)."""
        if self.speed is None or self.amplitude is None or self.band is None:
            raise ValueError("an excite on a goto needs the goto's speed, an amplitude and a band [low, high] (Hz)")
        if self.duration is not None:
            raise ValueError("an excite on a goto lasts the goto: no duration")
        if self.heading is not None:
            raise ValueError("an excite on a goto keeps the heading: turn in a hold before it")
        return self._check_signal()

    def _check_excite(self) -> "_SegmentSchema":
        if self.duration is None or self.amplitude is None or self.band is None:
            raise ValueError("an excite needs a duration (s), an amplitude and a band [low, high] (Hz)")
        if self.speed is not None or self.heading is not None:
            raise ValueError("an excite holds the pose: no speed or heading")
        if self.band[0] * self.duration < 1.0:
            raise ValueError(f"an excite of {self.duration:g} s is shorter than one period of its lowest "
                             f"frequency ({self.band[0]:g} Hz)")
        return self._check_signal()

    def _check_signal(self) -> "_SegmentSchema":
        if self.excite in TRANSLATIONS and isinstance(self.amplitude, str):
            raise ValueError(f"an excite on {self.excite} takes its amplitude in m, a number")
        if not _amplitude(self.excite, self.amplitude) > 0:
            raise ValueError("an excite's amplitude must be positive")
        low, high = self.band
        if not low < high:
            raise ValueError("an excite's band must be [low, high] with low < high (Hz)")
        return self


Tilt = Annotated[Angle, Field(gt=0, lt=math.pi / 2)]


class LimitsSchema(config.StrictModel):
    max_depth: Positive | None = None            # m
    max_tracking_error: Positive | None = None   # m
    max_thrust: Positive | None = None           # N per thruster
    max_tilt: Tilt | None = None                 # |roll| or |pitch|, rad or 'N deg' (run's default: 15 deg)


class _MissionSchema(config.StrictModel):
    name: Name
    description: str = ""
    start: _StartSchema
    ramp_time: Seconds = 2.0
    path: Annotated[list[_SegmentSchema], Field(min_length=1)]
    environment: EnvironmentSchema = EnvironmentSchema()
    limits: LimitsSchema = LimitsSchema()


@dataclass(frozen=True)
class Segment:
    """Motion from pose p0 (x, y, z, psi) to p1 along a 1-D speed profile over [t0, t0 + duration]."""

    t0: float
    duration: float
    p0: np.ndarray        # (4,) x, y, z, psi
    p1: np.ndarray        # (4,)
    ramp_in: float        # s, smooth speed ramp at the start (0: starts at full speed)
    ramp_out: float       # s, at the end (0: ends at full speed)
    extrapolate: bool     # keep moving at the final velocity after the end (a last line without ramp-out)
    excitation: Excitation | None = None   # an offset added over the segment (excite)
    terrain: tuple[str, float] | None = None   # ("altitude", m) or ("standoff", m): the depth made online

    def progress(self, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """sigma(tau), its first and second derivatives, sigma from 0 to 1 (tau in s since t0).

        Speed profile: a smoothstep ramp h(u) = 3u^2 - 2u^3 up, a cruise, a ramp down; continuous acceleration.
        Holds (no translation) use the same profile with both ramps spanning half the duration each."""
        T, ri, ro = self.duration, self.ramp_in, self.ramp_out
        speed = 1.0 / (T - 0.5 * (ri + ro))          # normalised cruise speed
        pos = np.empty_like(tau)
        vel = np.empty_like(tau)
        acc = np.empty_like(tau)
        up = tau < ri
        down = tau > T - ro
        mid = ~(up | down)
        u = tau[up] / ri if ri > 0 else tau[up]
        pos[up] = speed * ri * (u**3 - 0.5 * u**4)
        vel[up] = speed * (3 * u**2 - 2 * u**3)
        acc[up] = speed / ri * (6 * u - 6 * u**2) if ri > 0 else 0.0
        pos[mid] = speed * (0.5 * ri + (tau[mid] - ri))
        vel[mid] = speed
        acc[mid] = 0.0
        u = (T - tau[down]) / ro if ro > 0 else tau[down]
        pos[down] = 1.0 - speed * ro * (u**3 - 0.5 * u**4)
        vel[down] = speed * (3 * u**2 - 2 * u**3)
        acc[down] = -speed / ro * (6 * u - 6 * u**2) if ro > 0 else 0.0
        return pos, vel, acc


class Mission:
    """A validated mission: its reference trajectory, environment (simulation only) and limits (runs).

    `labels` name where each path entry came from in the source (default 'path[i]'; a QGroundControl plan's item);
    `origin` is (lat, lon) in degrees of local (0, 0) when the mission was planned on the globe; `skipped` lists
    the source's items left out (one line each). A mission deeper than its own `limits.max_depth` is refused."""

    def __init__(self, spec: _MissionSchema, source: str, labels: list[str] | None = None,
                 origin: tuple[float, float] | None = None, skipped: tuple[str, ...] = ()):
        self.spec = spec
        self.source = source
        self.name = spec.name
        self.environment = Environment.from_schema(spec.environment)
        self.limits = spec.limits
        self.labels = labels or [f"path[{i}]" for i in range(len(spec.path))]
        self.origin = origin
        self.skipped = skipped
        self.segments = _build_segments(spec, source, self.labels)
        self.duration = self.segments[-1].t0 + self.segments[-1].duration
        self._starts = np.array([seg.t0 for seg in self.segments])
        if spec.limits.max_depth is not None:
            self.check_depth(spec.limits.max_depth, "limits.max_depth")

    def check_depth(self, max_depth: float, limit: str) -> None:
        """ConfigError naming the first point of the path (start or a segment's end) deeper than `max_depth` m;
        `limit` names where the limit came from."""
        points = [("start", self.segments[0].p0)] + [(label, seg.p1) for label, seg in zip(self.labels,
                                                                                             self.segments)]
        for where, pose in points:
            if pose[2] > max_depth:
                raise config.ConfigError(f"{self.source}: {where}: depth {pose[2]:g} m is past {limit} "
                                         f"{max_depth:g} m")

    @property
    def start_pose(self) -> np.ndarray:
        """eta at t = 0, (6,)."""
        x, y, z = self.spec.start.position
        return np.array([x, y, z, 0.0, 0.0, self.spec.start.heading])

    def reference(self, t: np.ndarray | float) -> np.ndarray:
        """[eta_d, eta_dot_d, eta_ddot_d] at times t (s), shape t.shape + (18,).

        Before the first segment: the start pose; after the last: its end pose (or the line continued)."""
        t = np.asarray(t, dtype=float)
        flat = np.atleast_1d(t).ravel()
        out = np.zeros((flat.size, REFERENCE_COLUMNS))
        out[:, [0, 1, 2, 5]] = self.segments[0].p0
        starts = np.searchsorted(self._starts, flat, side="right") - 1    # the latest segment begun at each t
        for i in np.unique(starts[starts >= 0]):
            seg = self.segments[i]
            last = i == len(self.segments) - 1
            mask = starts == i if last else (starts == i) & (flat < seg.t0 + seg.duration)
            if not mask.any():
                continue
            tau = flat[mask] - seg.t0
            beyond = tau > seg.duration
            delta = seg.p1 - seg.p0
            sigma, dsigma, ddsigma = seg.progress(np.minimum(tau, seg.duration))
            if seg.extrapolate:
                sigma = sigma + np.where(beyond, (tau - seg.duration) * dsigma, 0.0)
            else:
                dsigma = np.where(beyond, 0.0, dsigma)
                ddsigma = np.where(beyond, 0.0, ddsigma)
            cols = [0, 1, 2, 5]
            out[np.ix_(mask, cols)] = seg.p0 + sigma[:, None] * delta
            out[np.ix_(mask, [c + 6 for c in cols])] = dsigma[:, None] * delta
            out[np.ix_(mask, [c + 12 for c in cols])] = ddsigma[:, None] * delta
            if seg.excitation is not None:
                pose, velocity, acceleration = seg.excitation.offset(tau)
                out[mask] += np.hstack([pose, velocity, acceleration])
        return out.reshape(t.shape + (REFERENCE_COLUMNS,))

    def sampled_reference(self, dt: float, duration: float | None = None) -> np.ndarray:
        """The reference at t_k = k dt, k = 0..N, N = round(duration / dt): (N + 1, 18)."""
        duration = self.duration if duration is None else duration
        n = int(round(duration / dt))
        if n < 1:
            raise config.ConfigError(f"{self.source}: duration {duration:g} s is shorter than one control period "
                                     f"({dt:g} s)")
        if n > MAX_SAMPLES:
            raise config.ConfigError(f"{self.source}: {duration:g} s in steps of {dt:g} s is more than "
                                     f"{MAX_SAMPLES:,} steps ({MAX_SAMPLES * dt:g} s): too long to hold in memory")
        return self.reference(np.arange(n + 1) * dt)

    @property
    def follows_terrain(self) -> bool:
        """Some leg holds an altitude or a standoff: its depth is made online from a sounder."""
        return any(seg.terrain is not None for seg in self.segments)

    def check_offline(self) -> None:
        """ConfigError when a leg's depth can only be made online (altitude, standoff): the offline loop has no
        bottom and no sounder."""
        if self.follows_terrain:
            label = next(lab for lab, seg in zip(self.labels, self.segments) if seg.terrain is not None)
            raise config.ConfigError(f"{self.source}: {label}: an altitude or standoff leg takes its depth from an "
                                     "echo sounder as it flies: fly it with `rov-mav run` (the built-in vehicle has "
                                     "a sounder); the offline loop has none")

    def terrain(self, t: float) -> tuple[str, float] | None:
        """The altitude or standoff held at mission time t (None: the planned depth)."""
        i = int(np.searchsorted(self._starts, t, side="right")) - 1
        return self.segments[max(i, 0)].terrain if t < self.duration else self.segments[-1].terrain

    def progress(self, t: float) -> float:
        """Fraction of the mission's planned duration elapsed at t, in [0, 1]."""
        return min(max(t / self.duration, 0.0), 1.0)


def _amplitude(axis: str, value: float | str) -> float:
    """An excite's amplitude in SI units: m for a translation, radians (from a number or 'N deg') for a rotation."""
    return float(value) if axis in TRANSLATIONS else parse_angle(value)


def _build_segments(spec: _MissionSchema, source: str, labels: list[str]) -> list[Segment]:
    pose = np.array([*spec.start.position, spec.start.heading], dtype=float)
    t = 0.0
    segments: list[Segment] = []
    for i, entry in enumerate(spec.path):
        where = f"{source}: {labels[i]}"
        last = i == len(spec.path) - 1
        if entry.goto is not None:
            target = np.array([*entry.goto[:2], entry.goto[2] if len(entry.goto) == 3 else pose[2], pose[3]])
            if entry.heading is not None:
                target[3] = pose[3] + wrap_angle(entry.heading - pose[3])
            length = float(np.linalg.norm(target[:3] - pose[:3]))
            if length < 1e-6:
                raise config.ConfigError(f"{where}.goto: zero-length segment (same point as the previous one)")
            ramp = min(spec.ramp_time, length / entry.speed)
            duration = length / entry.speed + ramp
            signal = None
            if entry.excite is not None:
                if entry.band[0] * duration < 1.0:
                    raise config.ConfigError(f"{where}: the goto lasts {duration:.3g} s, shorter than one period of "
                                             f"its excite's lowest frequency ({entry.band[0]:g} Hz)")
                signal = excitation(entry.excite, entry.signal, _amplitude(entry.excite, entry.amplitude),
                                    tuple(entry.band), duration, float(pose[3]))
            seg = Segment(t, duration, pose, target, ramp, ramp, False, signal)
        elif entry.excite is not None:
            signal = excitation(entry.excite, entry.signal, _amplitude(entry.excite, entry.amplitude),
                                tuple(entry.band), entry.duration, float(pose[3]))
            seg = Segment(t, entry.duration, pose, pose.copy(), 0.5 * entry.duration, 0.5 * entry.duration, False,
                          signal)
        elif entry.hold is not None:
            target = pose.copy()
            if entry.heading is not None:
                target[3] = pose[3] + wrap_angle(entry.heading - pose[3])
            seg = Segment(t, entry.hold, pose, target, 0.5 * entry.hold, 0.5 * entry.hold, False)
        else:
            velocity = np.array(entry.line)
            ramp_in = min(spec.ramp_time, 0.5 * entry.duration) if entry.ramp_up else 0.0
            ramp_out = 0.0 if last else min(spec.ramp_time, 0.5 * entry.duration)
            travel = entry.duration - 0.5 * (ramp_in + ramp_out)
            target = np.array([*(pose[:3] + velocity * travel), pose[3]])
            seg = Segment(t, entry.duration, pose, target, ramp_in, ramp_out, last and ramp_out == 0.0)
        if entry.altitude is not None or entry.standoff is not None:
            seg = replace(seg, terrain=("altitude", entry.altitude) if entry.altitude is not None else
                          ("standoff", entry.standoff))
        segments.append(seg)
        t += seg.duration
        pose = seg.p1
    if t > MAX_DURATION:
        raise config.ConfigError(f"{source}: path: lasts {t:.6g} s, more than {MAX_DURATION:g} s "
                                 f"({MAX_DURATION / 3600:g} h)")
    return segments


def load_mission(path: str | Path) -> Mission:
    """Load and validate a mission file; ConfigError (file, key, reason) before anything runs."""
    return Mission(config.load(_MissionSchema, path), str(path))


def mission_from_dict(data: dict, source: str, **extra) -> Mission:
    """A mission from the keys a mission file holds (built by another reader, e.g. of a QGroundControl plan);
    `extra` goes to `Mission` (labels, origin, skipped)."""
    return Mission(config.parse(_MissionSchema, data, source), source, **extra)
