"""Faults on the bridge's links, on purpose: loss, delay, jitter, duplication, reordering, a cut, dropped types.

`FaultSpec` says what to do; it is parsed from one option, 'loss=0.2,delay=50ms,jitter=10ms,dup=0.01,
reorder=0.05,cut=30s@20s', or from a YAML file holding the same keys. `Direction` applies it to one direction of
one link: `send(item, msg_id, t)` takes a message that left at vehicle time t, `due(t)` returns, in arrival order,
those that have arrived by vehicle time t. Each message, in this order: dropped if a cut covers t or its type is
dropped from then on; lost with probability `loss`; given the delay `delay` + uniform(-jitter, +jitter) (never
before an earlier message: jitter alone keeps the order); duplicated with probability `dup` (both copies arrive
together); with probability `reorder`, held back to arrive right after the next message in the same direction (or
REORDER_HOLD after its own arrival if no message follows). Times are vehicle seconds, so a bridge at --speedup N
delays N times less wall time. Every draw comes from one seeded `random.Random` per direction: a run is reproducible.
Pure: no I/O, no clock.
"""

from __future__ import annotations

import heapq
import itertools
import math
import random
from dataclasses import dataclass

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from rov_mav.fault_items import at_time, option_file, parse_item, seconds, split_items

REORDER_HOLD = 0.05            # vehicle s a held-back message waits for a successor to overtake it
PROBABILITIES = ("loss", "dup", "reorder")
DURATIONS = ("delay", "jitter")
KEYS = (*PROBABILITIES, *DURATIONS, "cut", "drop", "link")
EXAMPLE = "loss=0.2,delay=50ms,jitter=10ms,dup=0.01,reorder=0.05,cut=30s@20s,drop=PARAM_VALUE@40s,link=0"
_MESSAGE_IDS = {cls.msgname: msg_id for msg_id, cls in mavlink.mavlink_map.items()}


class FaultError(ValueError):
    """An invalid fault description; the message is one line naming the key and the problem."""


@dataclass(frozen=True)
class FaultSpec:
    """What to do to the messages of a link, both directions. Probabilities 0..1, times in vehicle s."""

    loss: float = 0.0
    delay: float = 0.0
    jitter: float = 0.0
    dup: float = 0.0
    reorder: float = 0.0
    cut: tuple[float, float] | None = None          # (start, duration): nothing sent in between arrives
    drop: tuple[tuple[str, float], ...] = ()        # (message name, from): that type never arrives from then on
    link: int | None = None                         # only this link (the endpoint's position), or all

    def applies_to(self, channel: int) -> bool:
        return self.link is None or self.link == channel

    def describe(self) -> str:
        parts = [f"{k}={getattr(self, k):g}" for k in PROBABILITIES if getattr(self, k)]
        parts += [f"{k}={getattr(self, k) * 1e3:g}ms" for k in DURATIONS if getattr(self, k)]
        if self.cut is not None:
            parts.append(f"cut={self.cut[1]:g}s@{self.cut[0]:g}s")
        parts += [f"drop={name}@{start:g}s" for name, start in self.drop]
        if self.link is not None:
            parts.append(f"link={self.link}")
        return ",".join(parts) or "none"


def _probability(key: str, text: str) -> float:
    text = text.strip()
    try:
        value = float(text[:-1]) / 100 if text.endswith("%") else float(text)
    except ValueError:
        value = math.nan
    if not 0.0 <= value <= 1.0:
        raise FaultError(f"{key}={text}: expected a probability from 0 to 1 (or 0% to 100%)")
    return value


def _duration(key: str, text: str) -> float:
    return seconds(text, FaultError, f"{key}={text}: expected a time of 0 or more with its unit, e.g. 50ms or 2s")


def _at(key: str, text: str, what: str) -> tuple[str, str]:
    head, start = at_time(text)
    if start is None or not head.strip():
        raise FaultError(f"{key}={text}: expected {what}@START, e.g. {key}=" + ("30s@20s" if key == "cut" else
                                                                             "PARAM_VALUE@40s"))
    return head.strip(), start


def _cut(text: str) -> tuple[float, float]:
    length, start = _at("cut", text, "LENGTH")
    try:
        duration, begin = _duration("cut", length), _duration("cut", start)
    except FaultError:
        raise FaultError(f"cut={text}: expected LENGTH@START, times of 0 or more with their unit, e.g. "
                         "cut=30s@20s") from None
    if duration <= 0:
        raise FaultError(f"cut={text}: the cut must last more than 0 s")
    return begin, duration


def _drop(text: str) -> tuple[str, float]:
    name, start = _at("drop", text, "MESSAGE") if "@" in text else (text.strip(), "0s")
    name = name.upper()
    if name not in _MESSAGE_IDS:
        raise FaultError(f"drop={text}: {name} is not a MAVLink message (e.g. PARAM_VALUE, COMMAND_ACK)")
    try:
        return name, _duration("drop", start)
    except FaultError:
        raise FaultError(f"drop={text}: expected MESSAGE@START, START a time of 0 or more with its unit, e.g. "
                         "drop=PARAM_VALUE@40s") from None


def _link(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = -1
    if value < 0:
        raise FaultError(f"link={text}: expected the position of an endpoint (0 for the first --out, or the "
                         "first --listen if there is no --out)")
    return value


def from_pairs(pairs: list[tuple[str, str]]) -> FaultSpec:
    """A FaultSpec from (key, value text) pairs; `drop` may repeat, other keys may not."""
    values: dict = {}
    drops = []
    for key, text in pairs:
        key = key.strip().lower()
        if key not in KEYS:
            raise FaultError(f"unknown fault '{key}': expected some of {', '.join(KEYS)} (e.g. {EXAMPLE})")
        if key == "drop":
            drops.append(_drop(text))
            continue
        if key in values:
            raise FaultError(f"{key} is given twice")
        if key in PROBABILITIES:
            values[key] = _probability(key, text)
        elif key in DURATIONS:
            values[key] = _duration(key, text)
        else:
            values[key] = _cut(text) if key == "cut" else _link(text)
    return FaultSpec(**values, drop=tuple(drops))


def parse_faults(text: str) -> FaultSpec:
    """'loss=0.2,delay=50ms,...' -> FaultSpec; FaultError (one line) if malformed."""
    pairs = []
    for one in map(parse_item, split_items(text) or [text]):
        if not one.assigned:
            raise FaultError(f"'{one.text}': expected KEY=VALUE (e.g. {EXAMPLE})")
        pairs.append((one.key, one.value))
    return from_pairs(pairs)


def load_faults(arg: str) -> FaultSpec:
    """The option's value: inline 'KEY=VALUE,...', or a YAML file of the same keys (drop may be a list)."""
    if "=" in arg:
        return parse_faults(arg)
    data, path = option_file(arg, FaultError, f"KEY=VALUE,..., e.g. {EXAMPLE}")
    pairs = []
    for key, value in data.items():
        for one in value if isinstance(value, list) and key == "drop" else [value]:
            pairs.append((str(key), str(one)))
    try:
        return from_pairs(pairs)
    except FaultError as exc:
        raise FaultError(f"{path}: {exc}") from None


class Direction:
    """One direction of one link under `spec`: what is sent, and when (vehicle s) it arrives."""

    def __init__(self, spec: FaultSpec, rng: random.Random):
        self.spec = spec
        self.rng = rng
        self.dropped_ids = {_MESSAGE_IDS[name]: start for name, start in spec.drop}
        self.sent = 0
        self.lost = 0
        self._queue: list[tuple[float, int, object]] = []      # (arrival, order, item): a heap
        self._order = itertools.count()
        self._last = -math.inf                                 # the latest arrival given so far
        self._held: tuple[object, float, int] | None = None    # (item, own arrival, copies) waiting to be passed

    def _chance(self, p: float) -> bool:
        return p > 0 and self.rng.random() < p

    def _blocked(self, msg_id: int, t: float) -> bool:
        cut = self.spec.cut
        if cut is not None and cut[0] <= t < cut[0] + cut[1]:
            return True
        start = self.dropped_ids.get(msg_id)
        return start is not None and t >= start

    def send(self, item, msg_id: int, t: float) -> None:
        """`item` (message id `msg_id`) leaves at vehicle time t."""
        spec = self.spec
        self.sent += 1
        if self._blocked(msg_id, t) or self._chance(spec.loss):
            self.lost += 1
            return
        jitter = self.rng.uniform(-spec.jitter, spec.jitter) if spec.jitter > 0 else 0.0
        arrival = max(t + spec.delay + jitter, t, self._last)
        self._last = arrival
        copies = 2 if self._chance(spec.dup) else 1
        if self._held is not None:             # the held-back message arrives right behind this one
            held, _, held_copies = self._held
            self._held = None
            self._push(item, arrival, copies)
            self._push(held, arrival, held_copies)
        elif self._chance(spec.reorder):
            self._held = (item, arrival, copies)
        else:
            self._push(item, arrival, copies)

    def _push(self, item, arrival: float, copies: int) -> None:
        for _ in range(copies):
            heapq.heappush(self._queue, (arrival, next(self._order), item))

    def due(self, t: float) -> list:
        """Everything that has arrived by vehicle time t, in arrival order."""
        if self._held is not None and self._held[1] + REORDER_HOLD <= t:
            item, arrival, copies = self._held
            self._held = None
            self._push(item, arrival + REORDER_HOLD, copies)
        out = []
        while self._queue and self._queue[0][0] <= t:
            out.append(heapq.heappop(self._queue)[2])
        return out


@dataclass
class LinkFaults:
    """Both directions of one link: `uplink` (to the vehicle) and `downlink` (from it)."""

    uplink: Direction
    downlink: Direction

    @classmethod
    def create(cls, spec: FaultSpec, seed: int, channel: int) -> "LinkFaults":
        """Each direction draws from its own generator, seeded by (seed, link, direction)."""
        return cls(Direction(spec, random.Random(f"{seed}/{channel}/up")),
                   Direction(spec, random.Random(f"{seed}/{channel}/down")))

    def describe(self) -> str:
        """What was done so far, e.g. 'to the vehicle 1200 sent, 361 lost (30.1 %); from it ...'."""
        return "; ".join(f"{name} {d.sent} sent, {d.lost} lost ({100 * d.lost / max(d.sent, 1):.1f} %)"
                         for name, d in (("to the vehicle", self.uplink), ("from it", self.downlink)))


def message_id(buf: bytes) -> int:
    """The message id in an encoded MAVLink 1 or 2 frame's header (-1 if it is not one)."""
    if len(buf) >= 10 and buf[0] == mavlink.PROTOCOL_MARKER_V2:
        return buf[7] | buf[8] << 8 | buf[9] << 16
    if len(buf) >= 6 and buf[0] == mavlink.PROTOCOL_MARKER_V1:
        return buf[5]
    return -1
