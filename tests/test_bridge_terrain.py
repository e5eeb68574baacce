"""The built-in vehicle over a bottom, with an echo sounder, as a ground station meets it over UDP: the sounder's own
DISTANCE_SENSOR from the companion, the autopilot's rangefinder (RNGFND1_*, its DISTANCE_SENSOR, RFTarget), the true
height beside the truth, and SURFTRAK holding the range up a slope a pilot drives along (`sim_bridge.modes.terrain`
for what is emulated and from which ArduSub source)."""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from bridge_helpers import BridgeProcess, Gcs, mavutil

from sim_bridge.modes.gates import MODES

pytestmark = pytest.mark.process
SPEEDUP = 5.0
SLOPE = {"depth": 8.0, "slope": 0.1}      # rising 10 % toward the north
NEUTRAL = [1500] * 8
FORWARD = [1500, 1500, 1500, 1500, 1600, 1500, 1500, 1500]


def environment(tmp_path, sounder="ping") -> str:
    path = tmp_path / "slope.yaml"
    path.write_text(yaml.safe_dump({"environment": {"seafloor": SLOPE, "navigation": {"preset": "ideal",
                                                                                      "echo_sounder": sounder}}}))
    return str(path)


def test_surftrak_holds_the_range_up_a_slope_and_the_link_says_what_a_real_one_does(tmp_path):
    logs = tmp_path / "logs"
    with BridgeProcess(tmp_path, "--environment", environment(tmp_path), "--start-depth", "6", "--param",
                       "FS_PILOT_INPUT=0", "--log-dir", str(logs), speedup=SPEEDUP) as bridge:
        gcs = Gcs(bridge.port, speedup=SPEEDUP, rate=5.0)
        try:
            gcs.connect()
            assert gcs.get_param("RNGFND1_TYPE").param_value == 10           # set up for the Ping, as BlueOS asks
            companion = gcs.recv("DISTANCE_SENSOR", cond=lambda m: m.get_srcComponent() == 194)
            assert (companion.get_srcSystem(), companion.orientation, companion.max_distance) == (1, 25, 12000)
            assert abs(companion.current_distance - 200) <= 5
            own = gcs.recv("DISTANCE_SENSOR", cond=lambda m: m.get_srcComponent() == 1)
            assert (own.id, own.orientation, own.min_distance, own.max_distance) == (0, 25, 20, 700)
            assert gcs.recv("NAMED_VALUE_FLOAT", cond=lambda m: m.name == "RFTarget").value == pytest.approx(-0.01)
            assert gcs.recv("NAMED_VALUE_FLOAT", cond=lambda m: m.name == "SimHeight").value == pytest.approx(2.0,
                                                                                                           abs=0.01)
            gcs.override = NEUTRAL
            gcs.start_pump()
            ack = gcs.request(lambda: gcs.send("set_mode", 1, 1, MODES["SURFTRAK"]), "HEARTBEAT",
                              lambda m: m.get_srcComponent() == 1 and m.custom_mode == MODES["SURFTRAK"])
            assert ack
            gcs.command(mavutil.mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1)
            text = gcs.recv("STATUSTEXT", cond=lambda m: m.text.startswith("rangefinder target is"))
            target = float(text.text.split()[3])
            assert target == pytest.approx(2.0, abs=0.1)
            gcs.override = FORWARD                                              # the pilot drives up the slope
            start = gcs.sim_time_now()
            heights, depths, rfs, now = [], [], [], start
            while now < start + 40.0:                                       # 40 s of the vehicle's time
                m = gcs.recv(["NAMED_VALUE_FLOAT", "SIM_STATE", "ATTITUDE"])
                if m.get_type() == "ATTITUDE":
                    now = m.time_boot_ms / 1000.0
                elif m.get_type() == "SIM_STATE":
                    depths.append(-m.alt)
                elif m.name == "SimHeight":
                    heights.append(m.value)
                elif m.name == "RFTarget":
                    rfs.append(m.value)
            gcs.override = NEUTRAL
        finally:
            gcs.close()
    heights = np.array(heights[len(heights) // 4:])        # after the first 10 s of the climb
    climbed = depths[0] - depths[-1]
    print(f"target {target:.2f} m, climbed {climbed:.2f} m, height {heights.mean():.3f} m mean, "
          f"{np.sqrt(np.mean((heights - target) ** 2)) * 100:.1f} cm RMS from the target")
    assert rfs and all(value == pytest.approx(target, abs=0.006) for value in rfs)   # the text says 2 decimals
    assert climbed > 0.5                                    # it went up the slope
    assert np.sqrt(np.mean((heights - target) ** 2)) < 0.15 and heights.min() > target - 0.3
    # the vehicle's own log, read by pymavlink's DataFlash reader: RFND as ArduSub writes it
    log = mavutil.mavlink_connection(str(next(logs.glob("*.BIN"))))
    rows = []
    while (m := log.recv_match(type="RFND")) is not None:
        rows.append((m.Instance, m.Dist, m.Stat, m.Orient, m.Quality))
    assert len(rows) > 100 and all(r[0] == 0 and r[3] == 25 for r in rows)
    good = [r for r in rows if r[2] == 4]
    assert len(good) > 0.95 * len(rows) and all(abs(r[1] - target) < 0.3 for r in good)
    assert sum(r[4] >= 90 for r in good) > 0.9 * len(good)          # the rest: the sounder's dropouts, quality 0


def test_without_a_bottom_in_view_the_sounder_says_invalid_and_surftrak_waits(tmp_path):
    deep = tmp_path / "deep.yaml"
    deep.write_text(yaml.safe_dump({"environment": {"navigation": {"echo_sounder": "ideal"}}}))
    with BridgeProcess(tmp_path, "--environment", str(deep), "--start-depth", "3", speedup=SPEEDUP) as bridge:
        gcs = Gcs(bridge.port, speedup=SPEEDUP)
        try:
            gcs.connect()
            seen = gcs.collect(2.0, ["DISTANCE_SENSOR"])
            gcs.send("set_mode", 1, 1, MODES["SURFTRAK"])
            answers = gcs.collect(2.0, ["STATUSTEXT", "HEARTBEAT"])
        finally:
            gcs.close()
    companion = [m for m in seen if m.get_srcComponent() == 194]
    assert companion and all(m.signal_quality == 1 for m in companion)     # pinging on, confidence 0: "invalid"
    assert any(m.get_type() == "HEARTBEAT" and m.custom_mode == MODES["SURFTRAK"] for m in answers)
    texts = [(m.text, m.severity) for m in answers if m.get_type() == "STATUSTEXT"]
    assert ("waiting for a rangefinder reading", 6) in texts
