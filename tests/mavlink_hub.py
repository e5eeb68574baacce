"""A companion computer's MAVLink router, as on a BlueROV2: every ground-side endpoint sees what the vehicle sends
and what every other endpoint sends (the pilot's station, a second script), and the vehicle sees one link."""

from __future__ import annotations

import select
import socket
import threading

MAX_DATAGRAM = 65535


class Hub:
    """UDP hub on `port` for ground stations, forwarding to and from a vehicle: one listening on udp `vehicle_port`
    (the bridge's udpin), or, without it, one that sends to `vehicle_port_bound` first (SITL's udpclient)."""

    def __init__(self, vehicle_port: int | None = None):
        self.ground = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.ground.bind(("127.0.0.1", 0))
        self.port = self.ground.getsockname()[1]
        self.vehicle = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.vehicle.bind(("127.0.0.1", 0))
        self.vehicle_port_bound = self.vehicle.getsockname()[1]
        self.vehicle_address = None if vehicle_port is None else ("127.0.0.1", vehicle_port)
        self.peers: list[tuple[str, int]] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def __enter__(self) -> "Hub":
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join(5)
        self.ground.close()
        self.vehicle.close()

    def _run(self) -> None:
        while not self._stop.is_set():
            readable, _, _ = select.select([self.ground, self.vehicle], [], [], 0.05)
            for sock in readable:
                try:
                    data, sender = sock.recvfrom(MAX_DATAGRAM)
                except OSError:          # ICMP unreachable from a peer that went away
                    continue
                if sock is self.vehicle:
                    self.vehicle_address = self.vehicle_address or sender
                    self._send_to_peers(data, None)
                    continue
                if sender not in self.peers:
                    self.peers.append(sender)
                self._send_to_peers(data, sender)
                if self.vehicle_address is not None:
                    try:
                        self.vehicle.sendto(data, self.vehicle_address)
                    except OSError:
                        pass

    def _send_to_peers(self, data: bytes, sender) -> None:
        for peer in self.peers:
            if peer != sender:
                try:
                    self.ground.sendto(data, peer)
                except OSError:
                    pass
