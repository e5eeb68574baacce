"""An echo sounder on the built-in vehicle, as BlueROV2s carry one (a Blue Robotics Ping): its figures (a `navigation:`
block's `echo_sounder:` section: `ping`, `ideal`, or the figures), what it measures and what it puts on the link.

What it measures: the distance along its beam to the nearest return within its cone (the axis and two rings of rays,
the beam's full width `beam`), from the body origin, down (or up, under ice) in body axes, to the environment's
seafloor (or ice ceiling; looking up without ice, the water's surface), so relief and slopes under the beam show and
a tilted vehicle reads a longer range. Blue Robotics' manual for the Ping (ping-sonar-technical-guide): 115 kHz, a
25-30 degree beam, 30-100 m of range; its tracking algorithm locks on the strongest return and low-passes the
distance, with a confidence figure. Here: the tracked distance moves `track` of the way to each ping's measurement;
the noise is `noise` + `noise_per_range` x range (the real sounder of mohai-2023-10-18-09-55-06-surftrak.tlog, at
6.5-10.6 m, differs by 2.5 cm RMS between consecutive readings, motion included: about 0.2 % of range per reading);
the confidence falls with the spread in depth of the returns within the cone (slopes, relief: 100 - 50 x spread
/ range, chosen), is 0 beyond `max_range` or inside `min_range`, and in a dropout (started at a ping with
`dropout_probability`, `dropout_duration` s on average); a false lock (kelp, a fish: `false_lock_probability` per
ping, `false_lock_duration` s on average) reads 30-90 % of the true range at a confidence of 60-100 (so some pass
ArduSub's RNGFND_SQ_MIN of 90); `outages` are dropouts at set times. The `ideal` sounder: the same cone and rate,
none of the errors.

On the link as BlueOS's Ping service sends it (the real log: DISTANCE_SENSOR from system 1, component 194, about
every 0.106 s, min_distance 20 and max_distance 12000 cm, type 1 ULTRASOUND, id 1, orientation 25 PITCH_270 (24
PITCH_90 looking up), covariance 255, horizontal and vertical fov 0.52 rad, a zero quaternion, signal_quality the
confidence with 0 sent as 1, "invalid"). The autopilot takes it as any DISTANCE_SENSOR
(`sim_bridge.autopilot.rangefinder`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Annotated, Literal

import numpy as np
from pydantic import Field
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from rov_mav import config
from rov_mav.model.dynamics import attitude_rotation
from rov_mav.model.navigation import NavigationError
from rov_mav.model.seafloor import Surface
from sim_bridge.gcs.telemetry import ENCODER

SECTION = "echo_sounder"
SOURCE = (1, 194)                      # (sysid, compid) of BlueOS's Ping service
DOWN, UP = mavlink.MAV_SENSOR_ROTATION_PITCH_270, mavlink.MAV_SENSOR_ROTATION_PITCH_90   # 25, 24
SENT_MIN_CM, SENT_MAX_CM = 20, 12000   # the service's fixed min_distance and max_distance
FOV = 0.52                             # rad: the service's horizontal and vertical fov
FIXED_POINT = 12                       # iterations of the beam's intersection with a surface
Rate = Annotated[float, Field(gt=0, le=50)]
NonNegative = Annotated[float, Field(ge=0)]
Probability = Annotated[float, Field(ge=0, le=1)]


class EchoSounderSchema(config.StrictModel):
    looking: Literal["down", "up"] = "down"
    rate: Rate = 9.4                   # Hz (the real log's median interval, 0.106 s)
    beam: Annotated[float, Field(gt=0, le=1.2)] = 0.52       # rad, full width
    min_range: NonNegative = 0.3       # m
    max_range: Annotated[float, Field(gt=0, le=300)] = 30.0   # m
    latency: Annotated[float, Field(ge=0, le=2)] = 0.05       # s from the ping to the link (chosen)
    noise: NonNegative = 0.005         # m
    noise_per_range: NonNegative = 0.002
    track: Annotated[float, Field(gt=0, le=1)] = 0.6          # share of the way to each measurement (1: none)
    dropout_probability: Probability = 0.002
    dropout_duration: Annotated[float, Field(gt=0)] = 1.5     # s, mean
    false_lock_probability: Probability = 0.001
    false_lock_duration: Annotated[float, Field(gt=0)] = 1.0  # s, mean
    outages: list[Annotated[list[Annotated[float, Field(ge=0)]], Field(min_length=2, max_length=2)]] = []
    # [start s, length s] of vehicle time when it has lost the bottom whatever the odds (a test's dropout)


IDEAL = EchoSounderSchema(noise=0.0, noise_per_range=0.0, track=1.0, dropout_probability=0.0,
                          false_lock_probability=0.0, latency=0.0)
PRESETS = {"ping": EchoSounderSchema(), "ideal": IDEAL}


@dataclass
class Sounding:
    t: float                           # s: the ping
    arrival: float                     # s: on the link
    distance: float                    # m, as reported
    confidence: int                    # 0-100
    true_range: float                  # m: the nearest return within the cone (inf: none)
    orientation: int


def figures(value) -> EchoSounderSchema:
    """A section's value: a preset name or a mapping (NavigationError, one line)."""
    if isinstance(value, str):
        if value.strip() not in PRESETS:
            raise NavigationError(f"navigation: {SECTION}: unknown preset '{value}' (one of {', '.join(PRESETS)}, "
                                  "or its figures)")
        return PRESETS[value.strip()]
    if not isinstance(value, dict):
        raise NavigationError(f"navigation: {SECTION}: expected a preset name or a mapping")
    base = figures(value.get("preset", "ping")).model_dump()          # a mapping: a preset's figures, then its own
    try:
        return config.parse(EchoSounderSchema, {**base, **{k: v for k, v in value.items() if k != "preset"}},
                            f"navigation: {SECTION}")
    except config.ConfigError as exc:
        raise NavigationError(str(exc)) from None


def beam_rays(beam: float) -> np.ndarray:
    """(17, 3) unit vectors in sensor axes (z along the beam): the axis and rings at half and the whole half-width."""
    rays = [np.array([0.0, 0.0, 1.0])]
    for cone in (beam / 4, beam / 2):
        for k in range(8):
            a = 2 * math.pi * k / 8
            rays.append(np.array([math.sin(cone) * math.cos(a), math.sin(cone) * math.sin(a), math.cos(cone)]))
    return np.array(rays)


def ranges(surface_depth, position: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Distance along each NED direction (N, 3) from `position` to the surface of depth `surface_depth(n, e)`
    (inf where the ray never meets it going that way): the fixed point of s = (depth(p + s d) - p_z) / d_z, which
    converges while the surface's slope times the ray's tangent stays below 1."""
    dz = directions[:, 2]
    alive = np.abs(dz) > 1e-9
    s = np.zeros(len(directions))
    for _ in range(FIXED_POINT):
        at = np.where(alive, s, 0.0)
        depth = surface_depth(position[0] + at * directions[:, 0], position[1] + at * directions[:, 1])
        s = (depth - position[2]) / np.where(alive, dz, 1.0)
        alive &= s >= 0                # the surface is behind the sensor (or the sensor beyond it)
    return np.where(alive, s, np.inf)


class EchoSounder:
    """One sounder: `sample(t, eta, nu)` gives the soundings on the link by t; `messages(sounding, ms)` their
    DISTANCE_SENSOR."""

    def __init__(self, value, seed: int, seafloor: Surface | None, ice: Surface | None):
        self.figures = f = figures(value)
        self.orientation = DOWN if f.looking == "down" else UP
        self._rays = beam_rays(f.beam) * (1.0 if f.looking == "down" else -1.0)
        target = seafloor if f.looking == "down" else ice
        self._depth = target.depth_at if target is not None else (
            None if f.looking == "down" else (lambda n, e: np.zeros_like(n)))
        self._rng = np.random.default_rng(np.random.SeedSequence([seed, 30]))
        self._period = 1.0 / f.rate
        self.next_event = 0.0                  # s: nothing is due before (a ping or a sounding's arrival)
        self._next_ping = 0.0
        self._tracked: float | None = None
        self._dropout_until = -math.inf
        self._lock_until, self._lock_share, self._lock_confidence = -math.inf, 1.0, 100
        self._pending: list[Sounding] = []

    def nearest(self, eta: np.ndarray) -> tuple[float, float]:
        """(the nearest return within the cone, the spread in depth of the returns across it: 0 on a flat, level
        surface, whatever the tilt) in m, from the pose eta."""
        if self._depth is None:
            return math.inf, 0.0
        directions = self._rays @ attitude_rotation(float(eta[3]), float(eta[4]), float(eta[5])).T
        s = ranges(self._depth, np.asarray(eta[:3], dtype=float), directions)
        hit = np.isfinite(s)
        if not hit.any():
            return math.inf, 0.0
        depths = s[hit] * directions[hit, 2]
        return float(s[hit].min()), float(depths.max() - depths.min())

    def sample(self, t: float, eta: np.ndarray, nu: np.ndarray) -> list[Sounding]:
        out = []
        if t + 1e-9 >= self._next_ping:
            self._next_ping = max(self._next_ping + self._period, t)
            self._pending.append(self._ping(t, eta))
        while self._pending and self._pending[0].arrival <= t + 1e-9:
            out.append(self._pending.pop(0))
        self.next_event = min([self._next_ping] + [p.arrival for p in self._pending[:1]])
        return out

    def _ping(self, t: float, eta: np.ndarray) -> Sounding:
        f, rng = self.figures, self._rng
        true_range, spread = self.nearest(eta)
        draws = rng.standard_normal()
        start_dropout, start_lock = rng.random() < f.dropout_probability, rng.random() < f.false_lock_probability
        span_dropout, span_lock = rng.exponential(f.dropout_duration), rng.exponential(f.false_lock_duration)
        share, lock_confidence = rng.uniform(0.3, 0.9), int(rng.integers(60, 101))
        if t >= self._dropout_until and start_dropout:
            self._dropout_until = t + span_dropout
        if t >= self._lock_until and start_lock:
            self._lock_until, self._lock_share, self._lock_confidence = t + span_lock, share, lock_confidence
        if not f.min_range <= true_range <= f.max_range:
            distance = f.min_range if true_range < f.min_range else self._tracked or 0.0
            return Sounding(t, t + f.latency, distance, 0, true_range, self.orientation)
        measured = true_range + (f.noise + f.noise_per_range * true_range) * draws
        confidence = max(0, min(100, round(100 - 50 * spread / max(true_range, 1e-6))))
        if t < self._lock_until:
            measured, confidence = true_range * self._lock_share, self._lock_confidence
        self._tracked = measured if self._tracked is None else self._tracked + f.track * (measured - self._tracked)
        if t < self._dropout_until or any(start <= t < start + length for start, length in f.outages):
            confidence = 0
        return Sounding(t, t + f.latency, max(self._tracked, 0.0), confidence, true_range, self.orientation)

    def messages(self, sounding: Sounding, time_boot_ms: int) -> list:
        """The Ping service's DISTANCE_SENSOR of a sounding, with its (sysid, compid)."""
        msg = ENCODER.distance_sensor_encode(time_boot_ms & 0xFFFFFFFF, SENT_MIN_CM, SENT_MAX_CM,
                                             min(round(sounding.distance * 100), 65535),
                                             mavlink.MAV_DISTANCE_SENSOR_ULTRASOUND, 1,
                                             sounding.orientation, 255, FOV, FOV, [0.0, 0.0, 0.0, 0.0],
                                             max(1, sounding.confidence))
        return [(msg, SOURCE)]
