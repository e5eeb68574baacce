"""MAVLink 2 transports of the emulated vehicle: udpout (send to a ground station), udpin and tcpin (answer whoever
writes). Non-blocking sockets, polled by the bridge's loop; one MAVLink encoder (sequence numbers) per link, and one
signing state (`sim_bridge.gcs.signing`) that its encoder and parsers share; frames the signature check refused are
counted in `rejections`.
A link given faults (`degrade`) passes every message, both ways, through them (sim_bridge/transport/faults.py): encoded
frames
on the way out (so a lost one leaves a gap in the sequence numbers), parsed messages on the way in; on tcpin whole
messages are lost or delayed, as behind a lossy radio bridged to TCP.
"""

from __future__ import annotations

import errno
import re
import socket
import time
from collections.abc import Callable

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from rov_mav.signing import Rejections, advance, check_signature_first
from sim_bridge.transport.faults import LinkFaults, message_id

KINDS = ("udpout", "udpin", "tcpin")
MAX_DATAGRAM = 65535
MAX_TCP_BACKLOG = 1 << 20        # bytes queued for a slow TCP client before it is dropped
HOST = re.compile(r"[A-Za-z0-9_](?:[A-Za-z0-9_.-]{0,252}[A-Za-z0-9_])?")   # a host name or an IPv4 address
UINT64_MASK = (1 << 64) - 1


class TransportError(Exception):
    """A link could not be opened; the message is one line naming the endpoint and the reason."""


def parse_endpoint(spec: str, kinds: tuple[str, ...] = KINDS) -> tuple[str, str, int]:
    """'KIND:HOST:PORT' -> (kind, host, port); TransportError if malformed (IPv6 is not spoken: IPv4 sockets)."""
    parts = spec.rsplit(":", 2)
    if len(parts) != 3 or parts[0] not in kinds or not parts[1]:
        wanted = " or ".join(k + ":HOST:PORT" for k in kinds) if len(kinds) < 3 else "/".join(kinds) + ":HOST:PORT"
        raise TransportError(f"{spec}: expected {wanted}")
    if not HOST.fullmatch(parts[1]):
        raise TransportError(f"{spec}: '{parts[1]}' is not a host name or IPv4 address")
    try:
        port = int(parts[2])
    except ValueError:
        port = -1
    if not 0 < port < 65536:
        raise TransportError(f"{spec}: port must be a number from 1 to 65535")
    return parts[0], parts[1], port


def _resolve(spec: str, host: str, port: int) -> tuple[str, int]:
    try:
        info = socket.getaddrinfo(host, port, socket.AF_INET, socket.SOCK_DGRAM)
    except socket.gaierror as exc:
        raise TransportError(f"{spec}: bad address: {exc.strerror}") from None
    return info[0][4]


def _os_error(spec: str, exc: OSError) -> TransportError:
    reason = "address already in use" if exc.errno == errno.EADDRINUSE else (exc.strerror or str(exc)).lower()
    return TransportError(f"{spec}: {reason}")


class _Peer:
    """A byte stream's parser (and, for TCP, its socket and unsent bytes)."""

    def __init__(self, signing, sock: socket.socket | None = None):
        self.sock = sock
        self.parser = mavlink.MAVLink(None)
        self.parser.robust_parsing = True
        self.parser.signing = signing
        check_signature_first(self.parser)
        self.backlog = b""


class Link:
    """One MAVLink link. `sockets()` for select, `receive()` drains it, `send(msg)` encodes and writes."""

    def __init__(self, spec: str, channel: int, sysid: int, compid: int = 1):
        self.spec = spec
        self.channel = channel
        self.kind, host, port = parse_endpoint(spec)
        self.address = _resolve(spec, host, port)
        self.encoder = mavlink.MAVLink(self, srcSystem=sysid, srcComponent=compid)
        self.signing = self.encoder.signing
        self._others: dict[tuple[int, int], mavlink.MAVLink] = {}   # other components' encoders (send_as)
        self.rejections = Rejections()
        self.peers: list[_Peer] = []
        self.udp_peer: tuple[str, int] | None = self.address if self.kind == "udpout" else None
        self.faults: LinkFaults | None = None
        self.clock: Callable[[], float] = lambda: 0.0
        try:
            if self.kind == "tcpin":
                self.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
                self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
                self.sock.bind(self.address)
                self.sock.listen(4)
            else:
                self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
                self.sock.bind(self.address if self.kind == "udpin" else ("0.0.0.0", 0))
                self.peers.append(_Peer(self.signing))
        except OSError as exc:
            self.sock.close()
            raise _os_error(spec, exc) from None
        self.sock.setblocking(False)

    def sockets(self) -> list[socket.socket]:
        return [self.sock] + [p.sock for p in self.peers if p.sock is not None]

    def degrade(self, faults: LinkFaults, clock: Callable[[], float]) -> None:
        """Pass every message through `faults` from now on; `clock()` is the vehicle time (s)."""
        self.faults, self.clock = faults, clock

    def receive(self) -> list:
        """Every complete MAVLink message that has arrived on this link (non-blocking)."""
        msgs = self._receive_tcp() if self.kind == "tcpin" else self._receive_udp()
        if self.faults is None:
            return msgs
        t = self.clock()
        for msg in msgs:
            self.faults.uplink.send(msg, msg.get_msgId(), t)
        return self.faults.uplink.due(t)

    def _receive_udp(self) -> list:
        out = []
        while True:
            try:
                data, sender = self.sock.recvfrom(MAX_DATAGRAM)
            except (BlockingIOError, InterruptedError):
                return out
            except OSError:          # e.g. ICMP port unreachable reported on a later call
                continue
            if self.kind == "udpin":
                self.udp_peer = sender
            out += self._parse(self.peers[0], data)

    def _receive_tcp(self) -> list:
        while True:
            try:
                client, _ = self.sock.accept()
            except (BlockingIOError, InterruptedError):
                break
            client.setblocking(False)
            client.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            self.peers.append(_Peer(self.signing, client))
        out = []
        for peer in list(self.peers):
            while True:
                try:
                    data = peer.sock.recv(MAX_DATAGRAM)
                except (BlockingIOError, InterruptedError):
                    break
                except OSError:
                    data = b""
                if not data:
                    self._drop(peer)
                    break
                out += self._parse(peer, data)
        return out

    def _parse(self, peer: _Peer, data: bytes) -> list:
        try:
            msgs = peer.parser.parse_buffer(data) or []
        except mavlink.MAVError:
            return []
        out = []
        for msg in msgs:
            if msg.get_type() != "BAD_DATA":
                out.append(msg)
            else:
                self.rejections.note(msg)
        return out

    def send(self, msg) -> None:
        """Encode `msg` with this link's sequence numbers (signed, when signing is on) and write it to every peer."""
        if self.signing.sign_outgoing:
            advance(self.signing, time.time())
            self.signing.timestamp &= UINT64_MASK     # a uint64_t in ArduPilot: a SETUP_SIGNING timestamp near 2^64
        self.encoder.send(msg)                        # wraps there, where pymavlink's struct.pack would fail

    def send_as(self, msg, source: tuple[int, int]) -> None:
        """Send `msg` as another (sysid, compid) on the vehicle's network sends it through the router (a BlueOS
        extension): its own sequence numbers, the link's signing."""
        encoder = self._others.get(source)
        if encoder is None:
            encoder = self._others[source] = mavlink.MAVLink(self, srcSystem=source[0], srcComponent=source[1])
            encoder.signing = self.signing
        if self.signing.sign_outgoing:
            advance(self.signing, time.time())
            self.signing.timestamp &= UINT64_MASK
        encoder.send(msg)

    def write(self, buf: bytes) -> None:
        """File interface used by the pymavlink encoder."""
        if self.faults is None:
            self._transmit(buf)
            return
        self.faults.downlink.send(buf, message_id(buf), self.clock())
        self.deliver()

    def deliver(self) -> None:
        """Transmit what the faults let arrive by now (the bridge calls this every step)."""
        if self.faults is not None:
            for buf in self.faults.downlink.due(self.clock()):
                self._transmit(buf)

    def _transmit(self, buf: bytes) -> None:
        if self.kind == "tcpin":
            for peer in list(self.peers):
                peer.backlog += buf
                self._flush(peer)
            return
        if self.udp_peer is None:       # udpin: nobody has written yet
            return
        try:
            self.sock.sendto(buf, self.udp_peer)
        except OSError:                  # a full socket buffer or an unreachable peer: the datagram is lost
            pass

    def _flush(self, peer: _Peer) -> None:
        try:
            n = peer.sock.send(peer.backlog)
        except (BlockingIOError, InterruptedError):
            n = 0
        except OSError:
            self._drop(peer)
            return
        peer.backlog = peer.backlog[n:]
        if len(peer.backlog) > MAX_TCP_BACKLOG:
            self._drop(peer)

    def _drop(self, peer: _Peer) -> None:
        peer.sock.close()
        self.peers.remove(peer)

    def restart(self, sysid: int) -> None:
        """The autopilot booted again: its sequence numbers restart at 0, under `sysid` (the stored one)."""
        self.encoder.seq = 0
        self.encoder.srcSystem = sysid

    def drop_clients(self) -> None:
        """Close every accepted TCP client, as an autopilot restarting does (UDP peers are kept)."""
        for peer in [p for p in self.peers if p.sock is not None]:
            self._drop(peer)

    def close(self) -> None:
        for peer in self.peers:
            if peer.sock is not None:
                peer.sock.close()
        self.peers.clear()
        self.sock.close()


def open_links(specs: list[str], sysid: int) -> list[Link]:
    """Open every endpoint in order (channel = position); on any failure close those opened and raise TransportError."""
    links: list[Link] = []
    try:
        for channel, spec in enumerate(specs):
            links.append(Link(spec, channel, sysid))
    except TransportError:
        for link in links:
            link.close()
        raise
    return links
