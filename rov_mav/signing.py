"""MAVLink 2 message signing, shared by the runner and the built-in vehicle: keys, timestamps, the frames a check
refused, and pymavlink's check put in the order of MAVLink's C library.

A key is 32 bytes: raw from a file, or the SHA-256 of an ASCII passphrase as MAVProxy derives it for `signing setup`
and `signing key` (MAVProxy/modules/mavproxy_signing.py, `passphrase_to_key`), so one passphrase serves both. A
signature carries the sender's link id and a 48-bit timestamp in 10 us since 2015-01-01 00:00 UTC; a receiver takes
each (link id, sysid, compid) stream's timestamps only increasing, a new stream only if it is at most a minute behind
its own timestamp, and moves its own up to every timestamp it accepts. pymavlink's `MAVLink.signing` signs and checks.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from rov_mav.config import ConfigError, read_bytes

KEY_BYTES = 32
EPOCH_2015 = 1_420_070_400          # unix s at 2015-01-01 00:00 UTC, where signing timestamps start
TICKS_PER_SECOND = 100_000          # signing timestamps count 10 us
UNSIGNED_RADIO = (mavlink.MAVLINK_MSG_ID_RADIO_STATUS, mavlink.MAVLINK_MSG_ID_RADIO)   # SiK radios never sign
VEHICLE_HEARTBEATS = 3              # rejected HEARTBEATs of an autopilot that show it does not sign with our key


def key_from_file(path: str | Path) -> bytes:
    """The 32 raw bytes of a key file (a regular file: a FIFO or device is refused, not read); ConfigError (one
    line) for anything else."""
    try:
        data = read_bytes(path)
    except ConfigError as exc:
        raise ConfigError(f"--signing-key {exc}") from None
    if len(data) != KEY_BYTES:
        raise ConfigError(f"--signing-key {path}: a key file holds exactly {KEY_BYTES} raw bytes, this one "
                          f"{len(data)} (make one with `head -c 32 /dev/urandom > FILE`, or use --signing-passphrase)")
    return data


def key_from_passphrase(passphrase: str) -> bytes:
    """SHA-256 of the passphrase's ASCII bytes, as MAVProxy's signing module derives a key."""
    if not passphrase:
        raise ConfigError("--signing-passphrase: empty")
    if not passphrase.isascii():
        raise ConfigError("--signing-passphrase: only ASCII characters (MAVProxy hashes the passphrase as ASCII)")
    return hashlib.sha256(passphrase.encode("ascii")).digest()


def timestamp(unix_seconds: float) -> int:
    """A signing timestamp: 10 us units since 2015-01-01 00:00 UTC."""
    return int((max(unix_seconds, EPOCH_2015) - EPOCH_2015) * TICKS_PER_SECOND)


def advance(signing, unix_seconds: float) -> None:
    """Keep a pymavlink `MAVLinkSigning`'s next outgoing timestamp at least at the clock's (ArduPilot's
    `GCS_MAVLINK::update_signing_timestamp` when its clock is set; MAVProxy's signing `idle_task`)."""
    signing.timestamp = max(signing.timestamp, timestamp(unix_seconds))


def check_signature_first(mav) -> None:
    """Make a pymavlink `MAVLink` leave a stream's last timestamp alone when a frame's signature is wrong.

    MAVLink's C library (mavlink_helpers.h, `mavlink_signature_check`, which ArduPilot runs) compares the signature
    first and only then looks at the stream's timestamp; pymavlink records the timestamp before it compares, so a
    frame signed with a wrong key and a later timestamp would lock the genuine sender of that stream out."""
    check = mav.check_signature

    def checked(msgbuf, src_system: int, src_component: int) -> bool:
        stream = (msgbuf[-13], src_system, src_component)
        streams = mav.signing.stream_timestamps
        before = streams.get(stream)
        if check(msgbuf, src_system, src_component):
            return True
        if before is None:
            streams.pop(stream, None)
        else:
            streams[stream] = before
        return False

    mav.check_signature = checked


@dataclass(frozen=True)
class Rejected:
    """A frame the signature check refused, read without checking: who it claims to be from, and what."""

    sysid: int
    compid: int
    message: object                   # the decoded message (unverified)
    signed: bool                      # carried a signature (with another key, or an old timestamp)

    def describe(self) -> str:
        how = "signed with another key or an old timestamp" if self.signed else "unsigned"
        return f"{self.message.get_type()} from {self.sysid}/{self.compid}, {how}"


class Rejections:
    """Frames a signature check refused (pymavlink hands them on as BAD_DATA "Invalid signature"): counted, the
    first kept, `on_first(rejected)` called once."""

    def __init__(self, on_first=None):
        self.count = 0
        self.first: Rejected | None = None
        self.vehicle_heartbeats = 0       # rejected HEARTBEATs of an autopilot
        self.first_vehicle_heartbeat: Rejected | None = None
        self.on_first = on_first
        self._reader = mavlink.MAVLink(None)      # no key: reads a frame without checking it

    def note(self, bad_data) -> Rejected | None:
        """Count `bad_data` if the signature check refused it; returns what it was."""
        if getattr(bad_data, "reason", None) != "Invalid signature":
            return None
        frame = bytearray(bad_data.data)
        try:
            msg = self._reader.decode(frame)
        except mavlink.MAVError:
            return None
        rejected = Rejected(msg.get_srcSystem(), msg.get_srcComponent(), msg,
                            frame[0] == mavlink.PROTOCOL_MARKER_V2 and bool(frame[2] & mavlink.MAVLINK_IFLAG_SIGNED))
        self.count += 1
        if msg.get_type() == "HEARTBEAT" and msg.autopilot != mavlink.MAV_AUTOPILOT_INVALID:
            self.vehicle_heartbeats += 1
            self.first_vehicle_heartbeat = self.first_vehicle_heartbeat or rejected
        if self.first is None:
            self.first = rejected
            if self.on_first is not None:
                self.on_first(rejected)
        return rejected

    def summary(self) -> str:
        return (f"signing: {self.count} message(s) not signed with our key ignored (the first: "
                f"{self.first.describe()})")
