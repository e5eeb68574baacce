"""MAVLink 2 signing as ArduSub 4.5 does it (libraries/GCS_MAVLink/GCS_Signing.cpp), over every link of the bridge.

- One key for the vehicle: given at start (a key ArduSub already holds) or set by SETUP_SIGNING. With a key, every
  link signs what it sends, with the link's number as link id (`GCS_MAVLINK::load_signing_key`), and takes only
  frames signed with the key whose timestamp is newer than the last of its (link id, sysid, compid) stream, the
  streams shared by every link (`signing_streams`). Unsigned or wrongly signed frames are dropped, except RADIO_STATUS
  and RADIO, and except on link 0, which stands for ArduPilot's channel 0 (USB on a flight controller) and is taken as
  secure: it accepts anything (`accept_unsigned_callback`).
- SETUP_SIGNING is a message like any other: it is handled when it passed those checks, so unsigned only on link 0
  or while the vehicle has no key, otherwise signed with the current key. Refused while armed
  (`handle_setup_signing`: "Won't setup signing when armed"). It stores the key and its initial timestamp; an all-zero
  key with timestamp 0 turns signing off.
- The outgoing timestamp starts a minute past the stored one (`load_signing_key`), never falls behind the host's clock
  (ArduPilot raises it whenever its real-time clock is set, from GPS or a companion's SYSTEM_TIME:
  `update_signing_timestamp`), and moves up to every timestamp it accepts.
ArduSub 4.5.3 SITL behaves so, measured: unsigned requests on SERIAL1/2 unanswered, on SERIAL0 answered; each
SERIALn signs with link id n.
"""

from __future__ import annotations

from collections.abc import Callable

from rov_mav.signing import KEY_BYTES, TICKS_PER_SECOND, UNSIGNED_RADIO, timestamp

SECURE_CHANNEL = 0
LOAD_MARGIN = 60 * TICKS_PER_SECOND       # `load_signing_key` starts a minute past the stored timestamp
ARMED_REFUSAL = "ERROR: Won't setup signing when armed"


def accepts_unsigned(channel: int, msg_id: int) -> bool:
    """`accept_unsigned_callback`: channel 0 takes anything, the others only what a radio sends."""
    return channel == SECURE_CHANNEL or msg_id in UNSIGNED_RADIO


class VehicleSigning:
    """The vehicle's key and stored timestamp, applied to the `MAVLinkSigning` state each link shares between its
    encoder and its parsers."""

    def __init__(self, key: bytes | None, unix_now: float):
        if key is not None and len(key) != KEY_BYTES:
            raise ValueError(f"a signing key is {KEY_BYTES} bytes")
        self.key = key
        self.stored_timestamp = timestamp(unix_now) if key is not None else 0
        self.streams: dict = {}                # (link id, sysid, compid) -> last timestamp, for every link
        self.links: list = []
        self.on_change: Callable[[str], None] | None = None    # told when SETUP_SIGNING changed the key

    @property
    def enabled(self) -> bool:
        return self.key is not None

    def attach(self, links: list) -> None:
        self.links = list(links)
        for link in self.links:
            self._apply(link)

    def setup(self, key: bytes, initial_timestamp: int, source: str) -> None:
        """SETUP_SIGNING from `source` (`handle_setup_signing` then `load_signing_key`): store, and apply on every
        link at once."""
        disable = initial_timestamp == 0 and not any(key)
        self.key = None if disable else bytes(key)
        self.stored_timestamp = 0 if disable else initial_timestamp
        for link in self.links:
            self._apply(link)
        if self.on_change is not None:
            self.on_change(f"signing {'turned off' if disable else 'key set'} by SETUP_SIGNING from {source}")

    def _apply(self, link) -> None:
        state = link.signing
        if self.key is None:
            state.secret_key, state.sign_outgoing, state.allow_unsigned_callback = None, False, None
            return
        state.secret_key = self.key
        state.sign_outgoing = True
        state.link_id = link.channel
        state.timestamp = self.stored_timestamp + LOAD_MARGIN
        state.stream_timestamps = self.streams
        state.allow_unsigned_callback = lambda _mav, msg_id, channel=link.channel: accepts_unsigned(channel, msg_id)

