"""AUTO on the built-in vehicle as a ground station meets it over UDP (`rov-mav sim-bridge` in a process of its own):
a mission of waypoints 1 m above a sloping bottom, in the terrain frame, uploaded by the mission protocol and flown
from the echo sounder's ranges, judged on the true height the bridge puts on the link (`sim_bridge.modes.auto` for
what is emulated and from which ArduSub source)."""

from __future__ import annotations

import time

import numpy as np
import pytest
import yaml
from auto_helpers import ORIGIN, TERRAIN, lat_lon_e7
from bridge_helpers import RETRY, WAIT, BridgeProcess, Gcs, mavutil

from rov_mav.units import north_east
from sim_bridge.modes.gates import MODES

pytestmark = pytest.mark.process
mav = mavutil.mavlink
AUTO = MODES["AUTO"]
SPEEDUP = 5.0
SLOPE = {"depth": 8.0, "slope": 0.1}             # rising 10 % toward the north
# (north m, east m, m above the bottom, hold s): three legs up the slope, the last turning east
WAYPOINTS = [(3.0, 0.0, 1.0, 0), (10.0, 0.0, 1.0, 0), (15.0, 4.0, 1.0, 2)]
NEUTRAL = [1500] * 8
FLIGHT = 90.0                                    # s of vehicle time the mission may take (it needs about 30)


def environment(tmp_path) -> str:
    path = tmp_path / "slope.yaml"
    sounder = {"dropout_probability": 0.0, "false_lock_probability": 0.0}    # the Ping's noise, no lost bottom
    path.write_text(yaml.safe_dump({"environment": {"seafloor": SLOPE, "navigation": {"preset": "ideal",
                                                                                      "echo_sounder": sounder}}}))
    return str(path)


def upload(gcs: Gcs, items: list[tuple]) -> None:
    """The mission protocol as a ground station speaks it: MISSION_COUNT, an item for each request, the ACK."""
    gcs.drop_queued()
    deadline = time.monotonic() + WAIT * 2
    gcs.send("mission_count", 1, 1, len(items), mav.MAV_MISSION_TYPE_MISSION)
    while time.monotonic() < deadline:
        m = gcs.recv(["MISSION_REQUEST", "MISSION_REQUEST_INT", "MISSION_ACK"], WAIT)
        if m.get_type() == "MISSION_ACK":
            assert m.type == mav.MAV_MISSION_ACCEPTED, m
            return
        frame, command, hold, x, y, z = items[m.seq]
        gcs.send("mission_item_int", 1, 1, m.seq, frame, command, 0, 1, hold, 0, 0, 0, x, y, z,
                 mav.MAV_MISSION_TYPE_MISSION)
    raise AssertionError("the upload did not end")


def test_auto_flies_terrain_waypoints_a_metre_above_a_slope_and_holds_at_the_end(tmp_path):
    home = (0, mav.MAV_CMD_NAV_WAYPOINT, 0, round(ORIGIN[0] * 1e7), round(ORIGIN[1] * 1e7), 0.0)
    items = [home] + [(TERRAIN, mav.MAV_CMD_NAV_WAYPOINT, hold, *lat_lon_e7(n, e), h) for n, e, h, hold in WAYPOINTS]
    with BridgeProcess(tmp_path, "--environment", environment(tmp_path), "--start-depth", "6", "--param",
                       "FS_PILOT_INPUT=0", speedup=SPEEDUP) as bridge:
        gcs = Gcs(bridge.port, speedup=SPEEDUP, rate=5.0)
        try:
            gcs.connect()
            gcs.override = NEUTRAL
            gcs.start_pump()
            upload(gcs, items)
            gcs.command(mav.MAV_CMD_COMPONENT_ARM_DISARM, 1)
            gcs.recv("NAMED_VALUE_FLOAT", cond=lambda m: m.name == "SimHeight")     # the sounder's ranges are in
            log = fly(gcs)
        finally:
            gcs.close()
    reached, texts = log["reached"], log["texts"]
    assert [seq for seq, _ in reached] == [1, 2, 3], (reached, texts)
    assert [t for t in texts if t.startswith(("Mission:", "Reached"))] == [
        "Mission: 1 WP", "Reached command #1", "Mission: 2 WP", "Reached command #2", "Mission: 3 WP",
        "Reached command #3"], texts
    first, last = reached[0][1], reached[-1][1]
    legs = np.array([h for t, h in log["heights"] if first <= t <= last])
    rms = float(np.sqrt(np.mean((legs - 1.0) ** 2)))
    print(f"{len(legs)} heights from waypoint 1 to 3: {legs.mean():.3f} m mean, {rms * 100:.1f} cm RMS, "
          f"{legs.min():.2f}..{legs.max():.2f} m; mission {last - log['start']:.1f} s")
    assert len(legs) > 50 and rms < 0.15 and np.abs(legs - 1.0).max() < 0.4
    # the end (`exit_mission`): still armed in AUTO, the mission complete, the stopping point held at its depth
    assert log["current"][-1] == (3, mav.MISSION_STATE_COMPLETE)
    assert log["heartbeats"] and all(mode == AUTO and armed for mode, armed in log["heartbeats"])
    end = np.array([p for t, p in log["positions"] if t > last + 4.0])
    assert len(end) > 10
    assert np.hypot(end[-1][0] - 15.0, end[-1][1] - 4.0) < 2.0                 # within WP_RADIUS_M
    assert np.ptp(end[:, 0]) < 0.5 and np.ptp(end[:, 1]) < 0.5 and np.ptp(end[:, 2]) < 0.15


def fly(gcs: Gcs) -> dict:
    """AUTO asked for (SET_MODE, again each second until a HEARTBEAT says AUTO) and everything the link says until
    8 s of vehicle time after the last waypoint (or FLIGHT s): (t, true height), (t, true north, east, depth), the
    items reached, texts, MISSION_CURRENT (seq, state), HEARTBEAT (mode, armed) once in AUTO."""
    log = {"heights": [], "positions": [], "reached": [], "texts": [], "current": [], "heartbeats": []}
    start = now = gcs.sim_time_now()
    log["start"] = start
    deadline = time.monotonic() + FLIGHT / SPEEDUP * 4 + WAIT
    end = start + FLIGHT
    asked = -float("inf")
    while now < end and time.monotonic() < deadline:
        if not log["heartbeats"] and time.monotonic() - asked > RETRY:
            gcs.send("set_mode", 1, 1, MODES["AUTO"])
            asked = time.monotonic()
        m = gcs.recv(["ATTITUDE", "NAMED_VALUE_FLOAT", "SIM_STATE", "MISSION_ITEM_REACHED", "STATUSTEXT",
                      "MISSION_CURRENT", "HEARTBEAT"])
        kind = m.get_type()
        if kind == "ATTITUDE":
            now = m.time_boot_ms / 1000.0
        elif kind == "NAMED_VALUE_FLOAT" and m.name == "SimHeight":
            log["heights"].append((now, m.value))
        elif kind == "SIM_STATE":
            north, east = north_east(m.lat_int * 1e-7, m.lon_int * 1e-7, ORIGIN)   # SITL's degE7
            log["positions"].append((now, (north, east, -m.alt)))
        elif kind == "MISSION_ITEM_REACHED":
            log["reached"].append((m.seq, now))
            if m.seq == len(WAYPOINTS):
                end = now + 8.0
        elif kind == "STATUSTEXT":
            log["texts"].append(m.text)
        elif kind == "MISSION_CURRENT":
            log["current"].append((m.seq, m.mission_state))
        elif kind == "HEARTBEAT" and m.get_srcComponent() == 1 and (log["heartbeats"] or m.custom_mode == AUTO):
            log["heartbeats"].append((m.custom_mode, bool(m.base_mode & mav.MAV_MODE_FLAG_SAFETY_ARMED)))
    return log
