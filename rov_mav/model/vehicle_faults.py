"""Faults of the vehicle itself, on purpose: a thruster that stops, jams, weakens or turns backwards, a reboot, a leak,
a sagging battery, a lost position source, a failed depth sensor.

`VehicleFaults` says what strikes when (vehicle s since the start); it is parsed from one option,
'thruster=3:dead@60s,reboot@90s,leak@100s' (comma-separated items, times with their unit), or from a YAML file
holding `vehicle_faults:` as that text or as a list of items. Items:

- `thruster=N:dead@T`      motor N (1-8, the vehicle's motor numbering) gives no thrust from T on
- `thruster=N:stuck=PWM@T` it gives the thrust of PWM us whatever it is told (a jammed ESC input)
- `thruster=N:weak=K@T`    it gives K (0 < K < 1) of the thrust it is told (fouled by kelp or tether)
- `thruster=N:reversed@T`  it pushes the other way (a swapped motor lead after a repair)
- `reboot@T`               the autopilot browns out and boots again (repeatable)
- `leak@T`                 the leak sensor reads water from T on
- `battery=RATE@T`         the pack sags RATE volts per second (e.g. 0.05V/s) more than its own discharge, from T
                           (from 0 without @T), down to the failsafe thresholds it will cross
- `navigation-lost@T[+D]`  the horizontal position source is gone from T (for D, e.g. +20s; for good without it)
- `navigation-reset=N/E@T` the position estimate jumps N m north and E m east at T and stays so (a DVL's "set
                           position", a reset to a new acoustic fix): the vehicle has not moved, its belief has
- `depth-sensor@T`         the depth sensor (Bar30) fails from T on

A thruster fault acts on the plant, so offline runs take it too (`rov_mav.model.environment`); the others meet
the autopilot's logic and need the built-in vehicle. Pure: no I/O beyond reading the file, no clock.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rov_mav.fault_items import at_time, option_file, parse_item, seconds, split_items

THRUSTERS = 8
THRUSTER_KINDS = ("dead", "stuck", "weak", "reversed")
EVENTS = ("reboot", "leak", "depth-sensor")
KEYS = ("thruster", "battery", "navigation-lost", "navigation-reset", *EVENTS)
EXAMPLE = "thruster=3:dead@60s,reboot@90s,leak@100s,battery=0.05V/s,navigation-lost@30s+10s,depth-sensor@50s"
PWM_RANGE = (1100, 1900)       # us: a stuck input stays within what an ESC takes as a command
_RATE = re.compile(r"^\s*([0-9.eE+-]+)\s*V/s\s*$", re.IGNORECASE)


class VehicleFaultError(ValueError):
    """An invalid vehicle-fault description; the message is one line naming the item and the problem."""


@dataclass(frozen=True)
class ThrusterFault:
    """Motor `thruster` (1-based) from `at` s: dead, stuck at `value` us, weak with gain `value`, or reversed."""

    thruster: int
    kind: str
    at: float
    value: float = math.nan

    def describe(self) -> str:
        value = f"={self.value:g}" if self.kind in ("stuck", "weak") else ""
        return f"thruster={self.thruster}:{self.kind}{value}@{self.at:g}s"

    @property
    def gain(self) -> float:
        """What the thruster gives of what it is told (a stuck one: all of what its stuck input asks)."""
        return {"dead": 0.0, "weak": self.value, "reversed": -1.0}.get(self.kind, 1.0)


@dataclass(frozen=True)
class VehicleFaults:
    """What strikes the vehicle and when (vehicle s). Empty = a healthy vehicle."""

    thrusters: tuple[ThrusterFault, ...] = ()
    reboots: tuple[float, ...] = ()
    leak: float | None = None
    battery: tuple[float, float] | None = None           # (V/s of extra sag, from)
    navigation_lost: tuple[tuple[float, float], ...] = ()  # (from, for how long; inf = for good)
    navigation_resets: tuple[tuple[float, float, float], ...] = ()   # (at, north m, east m)
    depth_sensor: float | None = None

    def __bool__(self) -> bool:
        return bool(self.thrusters or self.reboots or self.leak is not None or self.battery is not None
                    or self.navigation_lost or self.navigation_resets or self.depth_sensor is not None)

    def describe(self) -> str:
        parts = [f.describe() for f in self.thrusters] + [f"reboot@{t:g}s" for t in self.reboots]
        if self.leak is not None:
            parts.append(f"leak@{self.leak:g}s")
        if self.battery is not None:
            parts.append(f"battery={self.battery[0]:g}V/s@{self.battery[1]:g}s")
        parts += [f"navigation-lost@{t:g}s" + (f"+{d:g}s" if math.isfinite(d) else "") for t, d in self.navigation_lost]
        parts += [f"navigation-reset={n:g}/{e:g}@{t:g}s" for t, n, e in self.navigation_resets]
        if self.depth_sensor is not None:
            parts.append(f"depth-sensor@{self.depth_sensor:g}s")
        return ",".join(parts) or "none"

    @property
    def autopilot_faults(self) -> list[str]:
        """The faults that need the built-in vehicle's autopilot (all but the thrusters'), by name."""
        names = (["reboot"] if self.reboots else []) + (["leak"] if self.leak is not None else [])
        names += (["battery"] if self.battery is not None else []) + (
            ["navigation-lost"] if self.navigation_lost else []) + (
            ["navigation-reset"] if self.navigation_resets else [])
        return names + (["depth-sensor"] if self.depth_sensor is not None else [])

    def thruster_effect(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """At vehicle time t: (gain (8,) of each thruster's thrust, stuck input (8,) in us or NaN). A later fault
        on the same thruster replaces an earlier one."""
        gain, stuck = np.ones(THRUSTERS), np.full(THRUSTERS, np.nan)
        for fault in sorted(self.thrusters, key=lambda f: f.at):
            if t >= fault.at:
                i = fault.thruster - 1
                gain[i] = fault.gain
                stuck[i] = fault.value if fault.kind == "stuck" else np.nan
        return gain, stuck

    def thruster_times(self) -> tuple[float, ...]:
        """The instants at which the thrusters' effect changes."""
        return tuple(sorted({f.at for f in self.thrusters}))

    def navigation_ok(self, t: float) -> bool:
        return not any(start <= t < start + length for start, length in self.navigation_lost)

    def navigation_offset(self, t: float) -> np.ndarray:
        """(3,) m NED: how far the position estimate has been moved by the resets up to t."""
        out = np.zeros(3)
        for at, north, east in self.navigation_resets:
            if t >= at:
                out[:2] += (north, east)
        return out

    def depth_sensor_ok(self, t: float) -> bool:
        return self.depth_sensor is None or t < self.depth_sensor

    def leaking(self, t: float) -> bool:
        return self.leak is not None and t >= self.leak

    def battery_sag(self, t: float) -> float:
        """Volts the pack has sagged by at t beyond its own discharge."""
        if self.battery is None:
            return 0.0
        rate, start = self.battery
        return rate * max(t - start, 0.0)


OFFLINE_VOLTAGE = 16.0        # V: the battery a stuck thruster's thrust is taken at offline (a charged 4S pack under load)


def wrench_map(faults: VehicleFaults, matrix: np.ndarray, thrust_of_pwm) -> tuple[float, np.ndarray, np.ndarray]:
    """The thruster faults as the offline loop meets them, in wrench space: (from when, F (6, 6), push (6,)) such
    that the thrusters give F tau + push of a wrench tau allocated by the pseudo-inverse of B (`matrix`, 6 x n):
    F = B diag(g) B+ with g each thruster's gain (a stuck one 0) and push = B s, s the thrust (`thrust_of_pwm`) of
    each stuck input. (inf, I, 0) without thruster faults; VehicleFaultError if they strike at different times (the
    offline loop has one instant)."""
    times = faults.thruster_times()
    if not times:
        return math.inf, np.eye(6), np.zeros(6)
    if len(times) > 1:
        raise VehicleFaultError(f"offline runs take thruster faults that strike together: got "
                                f"{', '.join(f'{t:g}s' for t in times)}")
    gain, stuck = faults.thruster_effect(times[0])
    held = ~np.isnan(stuck)
    pushing = np.zeros(len(gain))
    pushing[held] = thrust_of_pwm(stuck[held])
    gain = np.where(held, 0.0, gain)
    return times[0], matrix @ np.diag(gain) @ np.linalg.pinv(matrix), matrix @ pushing


def _time(item: str, text: str) -> float:
    return seconds(text, VehicleFaultError,
                   f"{item}: expected a time of 0 or more with its unit after @, e.g. 60s or 500ms")


def _split_at(item: str, body: str, what: str) -> tuple[str, str]:
    head, when = at_time(body)
    if when is None:
        raise VehicleFaultError(f"{item}: expected {what}@TIME, e.g. {what}@60s")
    return head, when


def _thruster(item: str, value: str) -> ThrusterFault:
    body, when = _split_at(item, value, "thruster=N:KIND")
    number, sep, kind = body.partition(":")
    try:
        thruster = int(number)
    except ValueError:
        thruster = 0
    if not sep or not 1 <= thruster <= THRUSTERS:
        raise VehicleFaultError(f"{item}: expected thruster=N:KIND@TIME with N from 1 to {THRUSTERS}, e.g. "
                                "thruster=3:dead@60s")
    kind, _, amount = kind.partition("=")
    kind = kind.strip().lower()
    if kind not in THRUSTER_KINDS:
        raise VehicleFaultError(f"{item}: unknown thruster fault '{kind}': expected dead, stuck=PWM, weak=K or "
                                "reversed")
    at = _time(item, when)
    if kind in ("dead", "reversed"):
        if amount:
            raise VehicleFaultError(f"{item}: '{kind}' takes no value")
        return ThrusterFault(thruster, kind, at)
    try:
        number = float(amount)
    except ValueError:
        number = math.nan
    if kind == "stuck" and not PWM_RANGE[0] <= number <= PWM_RANGE[1]:
        raise VehicleFaultError(f"{item}: expected stuck=PWM with PWM from {PWM_RANGE[0]} to {PWM_RANGE[1]} us, "
                                "e.g. stuck=1700")
    if kind == "weak" and not 0.0 < number < 1.0:
        raise VehicleFaultError(f"{item}: expected weak=K with 0 < K < 1 (the share of its thrust it still gives), "
                                "e.g. weak=0.3")
    return ThrusterFault(thruster, kind, at, number)


def _battery(item: str, value: str) -> tuple[float, float]:
    rate_text, sep, when = value.partition("@")
    match = _RATE.match(rate_text)
    rate = float(match.group(1)) if match else math.nan
    if not (math.isfinite(rate) and 0 < rate <= 10):
        raise VehicleFaultError(f"{item}: expected battery=RATE[@TIME] with RATE in volts per second, more than 0 "
                                "and at most 10, e.g. battery=0.05V/s")
    return rate, _time(item, when) if sep else 0.0


def _reset(item: str, value: str) -> tuple[float, float, float]:
    step, sep, when = value.partition("@")
    north, slash, east = step.partition("/")
    try:
        moved = (float(north), float(east)) if slash else (math.nan, math.nan)
    except ValueError:
        moved = (math.nan, math.nan)
    if not sep or not all(math.isfinite(v) and abs(v) <= 1000 for v in moved):
        raise VehicleFaultError(f"{item}: expected navigation-reset=NORTH/EAST@TIME in metres (at most 1000 each), "
                                "e.g. navigation-reset=0.8/0.6@60s")
    return _time(item, when), *moved


def _navigation(item: str, when: str) -> tuple[float, float]:
    start, sep, length = when.partition("+")
    duration = _time(item, length) if sep else math.inf
    if duration == 0:
        raise VehicleFaultError(f"{item}: the loss must last more than 0 s")
    return _time(item, start), duration


def parse_vehicle_faults(items: list[str]) -> VehicleFaults:
    """Items as in the module's grammar -> VehicleFaults; VehicleFaultError (one line) if one is malformed."""
    thrusters: list[ThrusterFault] = []
    reboots: list[float] = []
    navigation: list[tuple[float, float]] = []
    resets: list[tuple[float, float, float]] = []
    single: dict[str, object] = {}
    for one in map(parse_item, items):
        text, key, value, sep = one.text, one.key, one.value, one.assigned
        if key not in KEYS:
            raise VehicleFaultError(f"unknown vehicle fault '{text}': expected some of {', '.join(KEYS)} "
                                    f"(e.g. {EXAMPLE})")
        if key == "thruster":
            thrusters.append(_thruster(text, value))
            continue
        if key == "navigation-reset":
            resets.append(_reset(text, value))
            continue
        if key in single:
            raise VehicleFaultError(f"{key} is given twice")
        if key == "battery":
            single[key] = _battery(text, value)
            continue
        if sep or not value.startswith("@"):
            raise VehicleFaultError(f"{text}: expected {key}@TIME, e.g. {key}@60s")
        if key == "reboot":
            reboots.append(_time(text, value[1:]))
        elif key == "navigation-lost":
            navigation.append(_navigation(text, value[1:]))
        else:
            single[key] = _time(text, value[1:])
    return VehicleFaults(thrusters=tuple(thrusters), reboots=tuple(sorted(reboots)), leak=single.get("leak"),
                         battery=single.get("battery"), navigation_lost=tuple(sorted(navigation)),
                         navigation_resets=tuple(sorted(resets)),
                         depth_sensor=single.get("depth-sensor"))


def items_of(value: object, where: str) -> list[str]:
    """A `vehicle_faults` value from YAML (one text of comma-separated items, or a list of items) as items."""
    if isinstance(value, str):
        return split_items(value)
    if isinstance(value, list) and all(isinstance(v, str) for v in value):
        return [part for v in value for part in split_items(v)]
    raise VehicleFaultError(f"{where}: vehicle_faults: expected a text like '{EXAMPLE}' or a list of such items")


def load_vehicle_faults(arg: str) -> VehicleFaults:
    """The option's value: inline 'ITEM,ITEM,...', or a YAML file holding `vehicle_faults:` (text or list)."""
    if not Path(arg).exists() and ("@" in arg or "=" in arg):
        return parse_vehicle_faults(split_items(arg))
    data, path = option_file(arg, VehicleFaultError, f"ITEM,ITEM,..., e.g. {EXAMPLE}")
    if "vehicle_faults" not in data:
        raise VehicleFaultError(f"{path}: vehicle_faults: missing (e.g. vehicle_faults: \"{EXAMPLE}\")")
    try:
        return parse_vehicle_faults(items_of(data["vehicle_faults"], str(path)))
    except VehicleFaultError as exc:
        message = str(exc)
        raise VehicleFaultError(message if message.startswith(str(path)) else f"{path}: {message}") from None
