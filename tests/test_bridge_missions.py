"""The built-in vehicle keeps a mission as ArduSub does: one scripted ground-station exchange (upload, download,
mistakes, a stalled upload, clear) gives the same transcript against the bridge as against ArduSub 4.5.3 SITL (run
when ARDUSUB_SITL names the binary; the expected transcript was taken from it)."""

from __future__ import annotations

import math
import os
import time

os.environ["MAVLINK20"] = "1"
import pytest  # noqa: E402
from pymavlink import mavutil  # noqa: E402
from sitl_helpers import Sitl  # noqa: E402
from bridge_helpers import WAIT, BridgeThread  # noqa: E402

mav = mavutil.mavlink
# (command, frame, param1-4, lat, lon, alt) as a ground station uploads them; item 0 is home's slot.
UPLOAD = [
    (16, 0, (0, 0, 0, 0), 33.81, -118.39, 0.0),
    (16, 6, (3.7, 1.5, 2.0, 45.0), 33.8104, -118.3938, -3.25),      # hold 3.7 s, yaw 45: what survives?
    (19, 3, (12.4, 0, 0, 0), 33.8105, -118.3938, -4.0),             # NAV_LOITER_TIME
    (178, 2, (1, 0.4, -1, 0), 0, 0, 0.0),                          # DO_CHANGE_SPEED 0.4 m/s
    (16, 3, (0, 0, 0, math.nan), 0, 0, 0.0),                       # "here, at this depth"
]
EXPECTED = {
    "requested": [0, 1, 2, 3, 4],
    "upload_ack": mav.MAV_MISSION_ACCEPTED,
    "received_text": True,
    "count": 5,
    "current_total": 4,
    "items": [   # (frame, command, param1-4, x, y, z) as read back; item 0 is compared with HOME_POSITION
        (3, 16, (3.0, 0.0, 0.0, 0.0), 338104000, -1183938000, -3.25),
        (3, 19, (12.0, 0.0, 1.0, 0.0), 338105000, -1183938000, -4.0),
        (0, 178, (1.0, 0.4, -1.0, 0.0), 0, 0, 0.0),
        (3, 16, (0.0, 0.0, 0.0, 0.0), 0, 0, 0.0),
    ],
    "home_is_home_position": True,
    "past_end": ["MISSION_COUNT 5", f"MISSION_ACK {mav.MAV_MISSION_ERROR}"],
    "out_of_sequence": mav.MAV_MISSION_INVALID_SEQUENCE,
    "list_while_uploading": mav.MAV_MISSION_DENIED,
    "unknown_command": mav.MAV_MISSION_UNSUPPORTED,
    "stalled_ack": mav.MAV_MISSION_OPERATION_CANCELLED,
    "stalled_text": "Mission upload timeout",
    "stalled_total": 1,          # MISSION_COUNT 2 had cut the mission to 2 items before the upload stalled
    "cleared_ack": mav.MAV_MISSION_ACCEPTED,
    "cleared_count": 0,
}


class MissionClient:
    """A pymavlink ground station speaking the mission protocol to vehicle 1 (MAVProxy's source ids)."""

    def __init__(self, target: str):
        self.conn = mavutil.mavlink_connection(target, source_system=255, source_component=190)
        self.texts: list[str] = []

    def connect(self) -> None:
        deadline = time.monotonic() + WAIT * 3
        while time.monotonic() < deadline:
            self.conn.mav.heartbeat_send(mav.MAV_TYPE_GCS, mav.MAV_AUTOPILOT_INVALID, 0, 0, 0)
            if self.conn.recv_match(type="HEARTBEAT", blocking=True, timeout=0.5) is not None:
                return
        raise AssertionError("no HEARTBEAT")

    def next(self, kinds: list[str], timeout: float = WAIT):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            m = self.conn.recv_match(type=kinds + ["STATUSTEXT"], blocking=True, timeout=0.2)
            if m is None or m.get_srcSystem() != 1:
                continue
            if m.get_type() == "STATUSTEXT":
                self.texts.append(m.text)
                if "STATUSTEXT" not in kinds:
                    continue
            return m
        raise AssertionError(f"no {kinds} within {timeout} s")

    def fresh(self, kind: str):
        """The next `kind`, asked for with REQUEST_MESSAGE (both vehicles answer it)."""
        deadline = time.monotonic() + WAIT
        while time.monotonic() < deadline:
            self.conn.mav.command_long_send(1, 1, mav.MAV_CMD_REQUEST_MESSAGE, 0,
                                            getattr(mav, f"MAVLINK_MSG_ID_{kind}"), 0, 0, 0, 0, 0, 0)
            try:
                return self.next([kind], 1.0)
            except AssertionError:
                continue
        raise AssertionError(f"no {kind}")

    def vehicle_time(self) -> float:
        return self.fresh("SYSTEM_TIME").time_boot_ms / 1000.0

    def send_item(self, seq: int, command: int, frame: int, params, lat: float, lon: float, alt: float) -> None:
        self.conn.mav.mission_item_int_send(1, 1, seq, frame, command, 0, 1, *params, round(lat * 1e7),
                                            round(lon * 1e7), alt, 0)

    def upload(self, items) -> tuple[list[int], int]:
        """Answer each MISSION_REQUEST(_INT) with its item (each seq once); the seqs asked for and the final ACK."""
        self.conn.mav.mission_count_send(1, 1, len(items), 0)
        requested: list[int] = []
        while True:
            m = self.next(["MISSION_REQUEST", "MISSION_REQUEST_INT", "MISSION_ACK"])
            if m.get_type() == "MISSION_ACK":
                return requested, m.type
            if m.seq not in requested:
                requested.append(m.seq)
                self.send_item(m.seq, *items[m.seq])

    def ask(self, send, kinds: list[str]):
        send()
        return self.next(kinds)


def exchange(client: MissionClient) -> dict:
    """The scripted session; what the vehicle answered, in EXPECTED's terms."""
    out: dict = {}
    client.connect()
    home = client.fresh("HOME_POSITION")
    out["requested"], out["upload_ack"] = client.upload(UPLOAD)
    client.next(["MISSION_CURRENT"])          # settle: the text can follow the ACK
    out["received_text"] = "Flight plan received" in client.texts
    out["count"] = client.ask(lambda: client.conn.mav.mission_request_list_send(1, 1, 0), ["MISSION_COUNT"]).count
    out["current_total"] = client.next(["MISSION_CURRENT"]).total
    items = []
    for seq in range(out["count"]):
        m = client.ask(lambda s=seq: client.conn.mav.mission_request_int_send(1, 1, s, 0), ["MISSION_ITEM_INT"])
        items.append((m.frame, m.command, tuple(round(p, 6) for p in (m.param1, m.param2, m.param3, m.param4)),
                      m.x, m.y, round(m.z, 6)))
    out["home_is_home_position"] = items[0][:2] == (0, 16) and \
        (items[0][3], items[0][4]) == (home.latitude, home.longitude) and abs(items[0][5] - home.altitude / 1e3) < 0.01
    out["items"] = items[1:]
    client.conn.mav.mission_request_int_send(1, 1, 9, 0)
    past = [client.next(["MISSION_COUNT", "MISSION_ACK"]) for _ in range(2)]
    out["past_end"] = [f"{m.get_type()} {m.count if m.get_type() == 'MISSION_COUNT' else m.type}" for m in past]
    # mistakes during an upload: an item out of sequence, a download request, an unknown command
    client.conn.mav.mission_count_send(1, 1, 2, 0)
    client.next(["MISSION_REQUEST", "MISSION_REQUEST_INT"])
    out["out_of_sequence"] = client.ask(lambda: client.send_item(1, *UPLOAD[1]), ["MISSION_ACK"]).type
    client.send_item(0, *UPLOAD[0])
    client.next(["MISSION_REQUEST", "MISSION_REQUEST_INT"], WAIT)
    out["list_while_uploading"] = client.ask(lambda: client.conn.mav.mission_request_list_send(1, 1, 0),
                                             ["MISSION_ACK"]).type
    out["unknown_command"] = client.ask(lambda: client.send_item(1, 99, 3, (0, 0, 0, 0), 33.8, -118.3, -1.0),
                                        ["MISSION_ACK"]).type
    # a stalled upload: requests repeated about once a vehicle second, cancelled after 8
    start = client.vehicle_time()
    client.conn.mav.mission_count_send(1, 1, 2, 0)
    requests = 0
    while (m := client.next(["MISSION_REQUEST", "MISSION_REQUEST_INT", "MISSION_ACK"], WAIT * 3)).get_type() != \
            "MISSION_ACK":
        requests += 1
    stalled = client.vehicle_time() - start
    out["stalled_ack"] = m.type
    client.next(["MISSION_CURRENT"])
    out["stalled_text"] = next((t for t in client.texts if "upload timeout" in t), None)
    out["stalled_total"] = client.next(["MISSION_CURRENT"]).total
    out["cleared_ack"] = client.ask(lambda: client.conn.mav.mission_clear_all_send(1, 1, 0), ["MISSION_ACK"]).type
    out["cleared_count"] = client.ask(lambda: client.conn.mav.mission_request_list_send(1, 1, 0),
                                      ["MISSION_COUNT"]).count
    print(f"stalled upload: cancelled after {stalled:.2f} s of vehicle time, {requests} requests")
    assert 8.0 <= stalled <= 10.5 and requests >= 6
    return out


@pytest.mark.process
def test_the_bridge_keeps_a_mission_as_ardusub_does():
    with BridgeThread(speedup=10.0) as bridge:
        client = MissionClient(f"udpout:127.0.0.1:{bridge.port}")
        try:
            assert exchange(client) == EXPECTED
        finally:
            client.conn.close()
        assert bridge.bridge.handler_errors == 0


@pytest.mark.process
def test_ardusub_sitl_keeps_a_mission_as_the_bridge_expects(tmp_path):
    with Sitl(tmp_path / "sitl", speedup=2.0) as sitl:
        sitl.wait_for_port(sitl.port0)
        client = MissionClient(sitl.target)
        try:
            assert exchange(client) == EXPECTED
        finally:
            client.conn.close()
