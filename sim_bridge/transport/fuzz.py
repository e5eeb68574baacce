"""Hostile and broken MAVLink traffic for testing a vehicle, seeded and reproducible.

`Traffic(seed)` yields `Chunk`s: bytes to write to a link (one datagram on UDP, a piece of the stream on TCP).
Most chunks are well-formed MAVLink frames (a correct CRC) of every message type in pymavlink's ardupilotmega
dialect, each field drawn from its type's extremes (0, the type's minimum and maximum, -1, NaN, ±inf, float32's
largest and smallest, values a whisker either side of 1), from its MAVLink enum, or at random; arrays element by
element or all one extreme; strings of known parameter names, random text or invalid UTF-8. Source system and
component are random too, including the GCS sysid (255) and the vehicle's own (1), and targets are mostly the
vehicle or broadcast so that the vehicle acts on them. The rest are broken: bits flipped, frames cut short, several
frames (some broken) run together, a correct CRC over a payload of the wrong length, unknown message ids, signed
frames with a random signature, and plain random bytes.

Half the well-formed messages cycle through every type of the dialect (each round in a new random order), half come
from `focus`: the messages a vehicle acts on (commands, parameters, overrides, modes, stream requests,
the mission protocol).
"""

from __future__ import annotations

import random
import re
import struct
from collections import Counter
from dataclasses import dataclass

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink

GCS_SYSID = 255
FOCUS = ("HEARTBEAT", "COMMAND_LONG", "COMMAND_INT", "PARAM_SET", "PARAM_REQUEST_READ", "RC_CHANNELS_OVERRIDE",
         "MANUAL_CONTROL", "SET_MODE", "REQUEST_DATA_STREAM", "TIMESYNC", "FILE_TRANSFER_PROTOCOL", "MISSION_COUNT",
         "MISSION_ITEM_INT", "MISSION_ITEM", "MISSION_REQUEST_LIST", "MISSION_REQUEST_INT", "MISSION_CLEAR_ALL")
# Commands a vehicle acts on: a command field takes one of these half of the time.
FOCUS_COMMANDS = tuple(getattr(mavlink, f"MAV_CMD_{name}") for name in (
    "COMPONENT_ARM_DISARM", "DO_SET_MODE", "SET_MESSAGE_INTERVAL", "GET_MESSAGE_INTERVAL", "REQUEST_MESSAGE",
    "REQUEST_AUTOPILOT_CAPABILITIES", "PREFLIGHT_REBOOT_SHUTDOWN", "DO_SET_SERVO", "DO_MOTOR_TEST",
    "DO_SET_SAFETY_SWITCH_STATE", "PREFLIGHT_CALIBRATION", "DO_SEND_BANNER"))
# What a chunk is, and how often: well-formed messages alone or in a burst, then the broken kinds.
KIND_WEIGHTS = {"message": 55, "burst": 10, "bitflip": 10, "truncated": 7, "relength": 5, "unknown": 3, "signed": 3,
                "garbage": 7}
STX_V1, STX_V2 = 0xFE, 0xFD
SIGNED = 0x01
SIGNATURE_LEN = 13
_INT_LIMITS = {"b": (-2**7, 2**7 - 1), "B": (0, 2**8 - 1), "h": (-2**15, 2**15 - 1), "H": (0, 2**16 - 1),
               "i": (-2**31, 2**31 - 1), "I": (0, 2**32 - 1), "q": (-2**63, 2**63 - 1), "Q": (0, 2**64 - 1)}
_F32_MAX = float(np.finfo(np.float32).max)
_F32_TINY = float(np.finfo(np.float32).smallest_subnormal)
_NEAR_ONE = (float(np.nextafter(np.float32(1), np.float32(0))), float(np.nextafter(np.float32(1), np.float32(2))))
# Floats that mean something to a vehicle: modes, message ids, arm/disarm, force-arm magic, intervals, PWMs.
_MEANINGFUL = (0.5, 2.0, 19.0, 30.0, 33.0, 51.0, 128.0, 400.0, 1000.0, 1100.0, 1500.0, 1900.0, 21196.0, 65535.0,
               65536.0, 1e6, 2.0**31, 3.6e9, -3.6e9, 2.0**32, 1e7)
_EXTREME_FLOATS = (0.0, -0.0, 1.0, -1.0, float("nan"), float("inf"), -float("inf"), _F32_MAX, -_F32_MAX, _F32_TINY,
                   1e-10, *_NEAR_ONE)


@dataclass(frozen=True)
class Chunk:
    """Bytes for one write; `kind` from KIND_WEIGHTS; `types` the message types of its well-formed frames."""

    kind: str
    data: bytes
    types: tuple[str, ...] = ()


@dataclass(frozen=True)
class _Field:
    name: str
    code: str            # struct code
    count: int           # array length (string length for "s"), 1 for a scalar
    enum: str | None


def _fields(cls) -> list[_Field]:
    """The fields of message class `cls` in wire order."""
    items = re.findall(r"(\d*)([a-zA-Z])", cls.unpacker.format[1:])
    enums = cls.fieldenums_by_name
    return [_Field(name, code, int(count or 1), enums.get(name))
            for name, (count, code) in zip(cls.ordered_fieldnames, items)]


def _enum_values(name: str) -> tuple[int, ...]:
    return tuple(v for v, entry in mavlink.enums.get(name, {}).items() if not entry.name.endswith("_ENUM_END"))


class Traffic:
    """A seeded stream of chunks aimed at the vehicle with system id `vehicle_sysid`.

    `param_names` are names for PARAM_* messages' param_id (half of them; the rest random), `focus` the message
    types and `commands` the command ids drawn half of the time, `kinds` overrides KIND_WEIGHTS."""

    def __init__(self, seed: int, vehicle_sysid: int = 1, param_names: tuple[str, ...] = (),
                 focus: tuple[str, ...] = FOCUS, commands: tuple[int, ...] = FOCUS_COMMANDS,
                 kinds: dict[str, float] | None = None):
        self.rng = random.Random(seed)
        self.vehicle_sysid = vehicle_sysid
        self.param_names = tuple(param_names)
        self.classes = {cls.msgname: cls for cls in mavlink.mavlink_map.values()}
        self.fields = {name: _fields(cls) for name, cls in self.classes.items()}
        self.enums = {f.enum: _enum_values(f.enum) for fields in self.fields.values() for f in fields if f.enum}
        self.focus = tuple(focus)
        self.commands = tuple(commands)
        weights = KIND_WEIGHTS if kinds is None else kinds
        self.kinds, self.kind_weights = list(weights), list(weights.values())
        self._cycle: list[str] = []
        self.sent_kinds: Counter = Counter()
        self.sent_types: Counter = Counter()

    # -- chunks ----------------------------------------------------------------------------------------------

    def chunk(self) -> Chunk:
        """The next chunk (counted in `sent_kinds` and, for its well-formed frames, `sent_types`)."""
        kind = self.rng.choices(self.kinds, self.kind_weights)[0]
        chunk = getattr(self, f"_{kind}")()
        self.sent_kinds[kind] += 1
        self.sent_types.update(chunk.types)
        return chunk

    def _message(self) -> Chunk:
        name = self.message_type()
        return Chunk("message", self.frame(name), (name,))

    def _burst(self) -> Chunk:
        names = [self.message_type() for _ in range(self.rng.randint(2, 6))]
        return Chunk("burst", b"".join(self.frame(n) for n in names), tuple(names))

    def _bitflip(self) -> Chunk:
        data = bytearray(self.frame(self.message_type()))
        for _ in range(self.rng.randint(1, 8)):
            data[self.rng.randrange(len(data))] ^= 1 << self.rng.randrange(8)
        return Chunk("bitflip", bytes(data))

    def _truncated(self) -> Chunk:
        data = self.frame(self.message_type())
        return Chunk("truncated", data[:self.rng.randrange(1, len(data))])

    def _relength(self) -> Chunk:
        """A correct CRC over a payload of any length 0..255 of a known message id."""
        cls = self.classes[self.message_type()]
        payload = self.rng.randbytes(self.rng.randrange(256))
        return Chunk("relength", self._framed(cls.id, cls.crc_extra, payload, v1=cls.id < 256 and self.coin(0.2)))

    def _unknown(self) -> Chunk:
        msg_id = self.rng.choice([i for i in (self.rng.randrange(1 << 24) for _ in range(4))
                                  if i not in mavlink.mavlink_map] or [0xFFFFFF])
        return Chunk("unknown", self._framed(msg_id, self.rng.randrange(256), self.rng.randbytes(
            self.rng.randrange(256))))

    def _signed(self) -> Chunk:
        name = self.message_type()
        return Chunk("signed", self.frame(name, signed=True), (name,))

    def _garbage(self) -> Chunk:
        data = bytearray(self.rng.randbytes(self.rng.randint(1, 280)))
        for _ in range(self.rng.randint(0, 4)):
            data[self.rng.randrange(len(data))] = self.rng.choice((STX_V1, STX_V2))
        return Chunk("garbage", bytes(data))

    # -- well-formed messages --------------------------------------------------------------------------------

    def message_type(self) -> str:
        """A focus type half the time, else the next type of the dialect-wide cycle."""
        if self.focus and self.coin(0.5):
            return self.rng.choice(self.focus)
        if not self._cycle:
            self._cycle = sorted(self.classes)
            self.rng.shuffle(self._cycle)
        return self._cycle.pop()

    def payload(self, name: str) -> bytes:
        """A full-length payload of message `name` with every field drawn as the module docstring says."""
        values = []
        for f in self.fields[name]:
            if f.code == "s":
                values.append(self._string(f))
            elif f.count > 1:
                values.extend(self._array(f))
            else:
                values.append(self._value(f))
        return self.classes[name].unpacker.pack(*values)

    def frame(self, name: str, signed: bool = False) -> bytes:
        """Message `name` framed with a correct CRC: MAVLink 2 (trailing zeros stripped or not), or, sometimes and
        for ids below 256, MAVLink 1."""
        cls = self.classes[name]
        payload = self.payload(name)
        v1 = not signed and cls.id < 256 and self.coin(0.15)
        if not v1 and self.coin(0.7):
            payload = payload.rstrip(b"\0") or b"\0"
        return self._framed(cls.id, cls.crc_extra, payload, v1=v1, signed=signed)

    def _framed(self, msg_id: int, crc_extra: int, payload: bytes, v1: bool = False, signed: bool = False) -> bytes:
        seq, sysid, compid = self.rng.randrange(256), self.source_system(), self.source_component()
        if v1:
            header = struct.pack("<BBBBBB", STX_V1, len(payload), seq, sysid, compid, msg_id)
        else:
            header = struct.pack("<BBBBBBBHB", STX_V2, len(payload), SIGNED if signed else 0, 0, seq, sysid, compid,
                                 msg_id & 0xFFFF, msg_id >> 16)
        crc = mavlink.x25crc(header[1:] + payload)
        crc.accumulate(bytes([crc_extra]))
        frame = header + payload + struct.pack("<H", crc.crc)
        return frame + self.rng.randbytes(SIGNATURE_LEN) if signed else frame

    def source_system(self) -> int:
        return self.rng.choices((GCS_SYSID, self.vehicle_sysid, 0, self.rng.randint(1, 254)), (35, 15, 5, 45))[0]

    def source_component(self) -> int:
        return self.rng.choices((1, 190, 0, self.rng.randint(1, 255)), (25, 30, 5, 40))[0]

    # -- field values ----------------------------------------------------------------------------------------

    def coin(self, p: float) -> bool:
        return self.rng.random() < p

    def _value(self, f: _Field):
        if f.name in ("target_system", "target"):
            return self.rng.choices((self.vehicle_sysid, 0, self.rng.randrange(256)), (55, 30, 15))[0]
        if f.name == "target_component":
            return self.rng.choices((1, 0, self.rng.randrange(256)), (55, 30, 15))[0]
        if f.name == "command" and self.commands and self.coin(0.5):
            return self.rng.choice(self.commands)
        if f.enum and self.enums.get(f.enum) and f.code not in "fd" and self.coin(0.4):
            value = self.rng.choice(self.enums[f.enum])
            low, high = _INT_LIMITS[f.code]
            if low <= value <= high:
                return value
        return self._float() if f.code in "fd" else self._int(f.code)

    def _int(self, code: str) -> int:
        low, high = _INT_LIMITS[code]
        pool = [0, 1, low, high, high - 1, self.rng.randint(low, high), self.rng.randint(0, min(high, 300))]
        if low < 0:
            pool.append(-1)
        pool += [v for v in (1100, 1500, 1900, 65534) if v <= high]
        return self.rng.choice(pool)

    def _float(self) -> float:
        pick = self.rng.random()
        if pick < 0.35:
            return self.rng.choice(_EXTREME_FLOATS)
        if pick < 0.6:
            return self.rng.choice(_MEANINGFUL)
        if pick < 0.75:
            return float(self.rng.randint(-2, 300))
        if pick < 0.9:
            return self.rng.uniform(-2000.0, 2000.0)
        value = self.rng.choice((-1, 1)) * 10.0 ** self.rng.uniform(-45, 38.5)
        return value if abs(value) <= _F32_MAX else _F32_MAX

    def _array(self, f: _Field) -> list:
        if self.coin(0.3):
            return [self._value(f)] * f.count           # all one value: all NaN, all max, all zero...
        if f.code == "B" and self.coin(0.5):
            return list(self.rng.randbytes(f.count))
        return [self._value(f) for _ in range(f.count)]

    def _string(self, f: _Field) -> bytes:
        pick = self.rng.random()
        if f.name == "param_id" and self.param_names and pick < 0.5:
            return self.rng.choice(self.param_names).encode()[:f.count]
        if pick < 0.65:
            return b""
        if pick < 0.8:
            return bytes(self.rng.choice(b"ABCDEFGHIJKLMNOPQRSTUVWXYZ_0123456789") for _ in range(f.count))
        return self.rng.randbytes(f.count)             # any bytes: no terminator, invalid UTF-8, NULs inside
