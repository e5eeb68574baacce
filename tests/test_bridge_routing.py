"""The built-in vehicle's links as ArduSub's are: stations on different links of the vehicle see each other as
ArduPilot's routing lets them (`MAVLink_routing::check_and_forward`; on ArduSub 4.5.3 SITL, a station on SERIAL1
and a listener on SERIAL0: the station's HEARTBEAT reached the listener, its MANUAL_CONTROL, RC_CHANNELS_OVERRIDE and
COMMAND_LONG to the vehicle did not), and 4.7's MAV_GCS_SYSID_HI, MAV_OPTIONS and MAVn_OPTIONS. pymavlink stations
over real UDP against the bridge in-process."""

from __future__ import annotations

import time

import pytest
from bridge_helpers import BridgeThread, Gcs
from bridge_helpers import SPEEDUP

pytestmark = pytest.mark.process      # starts a process or the bridge (tests/conftest.py)

WATCH = 1.0         # wall s a listener watches for what must not arrive (10 vehicle s at SPEEDUP)


@pytest.fixture
def two_links():
    """A bridge with two links; a listener (sysid 200) on the first, connected; the second free for a station."""
    with BridgeThread(SPEEDUP, links=2) as b:
        listener = Gcs(b.ports[0], SPEEDUP, sysid=200)
        listener.connect()
        try:
            yield b, listener
        finally:
            listener.close()


def _from(listener: Gcs, sysid: int, seconds: float = WATCH) -> set[str]:
    """The kinds of message from `sysid` the listener received within `seconds` of wall time."""
    return {m.get_type() for m in listener.collect(seconds) if m.get_srcSystem() == sysid}


def test_a_stations_heartbeat_reaches_the_other_link_and_what_it_sends_the_vehicle_does_not(two_links):
    bridge, listener = two_links
    pilot = Gcs(bridge.ports[1], SPEEDUP, sysid=255, rate=25.0)
    try:
        pilot.connect()
        pilot.joystick = (600, 0, 500, 0)
        pilot.start_pump()
        listener.drop_queued()
        for _ in range(10):
            pilot.send("command_long", 1, 1, 400, 0, 0, 0, 0, 0, 0, 0, 0)     # disarm: for the vehicle alone
            time.sleep(0.02)
        heard = listener.collect(WATCH)
        assert {m.get_type() for m in heard if m.get_srcSystem() == 255} == {"HEARTBEAT"}
        # ... and yet the vehicle took the joystick: it shows in the RC input the listener is sent
        assert any(m.chan5_raw == 1620 for m in heard if m.get_type() == "RC_CHANNELS")
    finally:
        pilot.close()


def test_a_broadcast_goes_where_a_system_was_seen_and_a_private_link_gets_nothing(two_links):
    bridge, listener = two_links
    station = Gcs(bridge.ports[1], SPEEDUP, sysid=77)
    try:
        station.connect()
        listener.drop_queued()
        for _ in range(5):
            station.send("statustext", 6, b"hello from 77")           # no target: a broadcast
            time.sleep(0.02)
        assert "STATUSTEXT" in _from(listener, 77)
        assert station.set_param("MAV1_OPTIONS", 2).param_value == 2     # bit 1: link 0 private, from the next boot
        assert station.command(246, 1).result == 0                        # reboot
        station.recv("STATUSTEXT", cond=lambda m: m.text == "ArduPilot Ready")
        listener.drop_queued()
        for _ in range(5):
            station.heartbeat()
            station.send("statustext", 6, b"hello again")
            time.sleep(0.02)
        assert _from(listener, 77) == set()
    finally:
        station.close()


@pytest.mark.parametrize("sysid, drives", [(250, True), (255, True), (249, False)])
def test_a_gcs_id_range_takes_overrides_from_every_id_in_it(sysid, drives):
    """MAV_GCS_SYSID 250, MAV_GCS_SYSID_HI 255 (`GCS::sysid_is_gcs`)."""
    with BridgeThread(SPEEDUP) as b:
        gcs = Gcs(b.port, SPEEDUP, sysid=sysid, rate=25.0)
        try:
            gcs.connect()
            assert gcs.set_param("MAV_GCS_SYSID", 250).param_value == 250
            assert gcs.set_param("MAV_GCS_SYSID_HI", 255).param_value == 255
            gcs.override = [1700] * 8
            gcs.start_pump()
            time.sleep(0.5)
            start = gcs.sim_time_now()
            rcs = [m for m in gcs.collect(0.5, ["RC_CHANNELS"]) if m.time_boot_ms / 1000 > start]
            assert rcs and all((m.chan1_raw == 1700) == drives for m in rcs)
        finally:
            gcs.close()


def test_with_mav_options_bit_0_a_station_outside_the_gcs_ids_is_not_listened_to():
    with BridgeThread(SPEEDUP) as b:
        gcs = Gcs(b.port, SPEEDUP, sysid=255)
        other = Gcs(b.port, SPEEDUP, sysid=42)
        try:
            gcs.connect()
            assert other.request(lambda: other.send("param_request_read", 1, 1, b"MAV_OPTIONS", -1), "PARAM_VALUE",
                                 lambda m: m.param_id == "MAV_OPTIONS").param_value == 0
            assert gcs.set_param("MAV_OPTIONS", 1).param_value == 1
            other.drop_queued()
            other.send("param_request_read", 1, 1, b"MAV_OPTIONS", -1)
            assert not [m for m in other.collect(WATCH, ["PARAM_VALUE"]) if m.param_id == "MAV_OPTIONS"]
        finally:
            other.close()
            gcs.close()
