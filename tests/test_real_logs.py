"""The review held to real BlueROV2 logs nobody here wrote (ArduSub 4.1 to 4.6-dev, DataFlash and telemetry), each
against what pymavlink alone reads from the same file: ArduSub's own depth (CTUN.Alt, GLOBAL_POSITION_INT), its
arming (ARM / EV records, HEARTBEAT), its rangefinder's good readings (RFND.Stat 4), its mode numbers.

The logs stay outside the repository: ROVMAV_REAL_LOGS names their folder (`.ci/run` sets it to the logs beside the
checkout); without it every test here is skipped, saying so."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import numpy as np
import pytest
from pymavlink import DFReader, mavutil
from telemetry_helpers import read_column

from rov_mav import cli
from rov_mav.review.dive_review import review_dive

FOLDER = os.environ.get("ROVMAV_REAL_LOGS")
LOGS = sorted(p.name for p in Path(FOLDER).iterdir() if p.suffix in (".BIN", ".tlog")) if FOLDER and \
    Path(FOLDER).is_dir() else []
pytestmark = pytest.mark.skipif(not LOGS, reason="ROVMAV_REAL_LOGS does not name a folder of real logs (.ci/run "
                                                  "points it at the logs beside the checkout)")
ARM_EVENTS = {10: True, 11: False}         # EV ids (AP_Logger/LogStructure.h): armed, disarmed
GOOD = 4                                   # RFND.Stat: RangeFinder::Status::Good
DOWN = 25                                  # RFND.Orient: pitch 270, looking down
DIVE = 1.0                                 # m: ArduSub's own depth beyond this is a dive; on the bench (the Bar30 in
                                           # air) its EKF altitude wanders by up to 0.56 m in these logs


@pytest.fixture(scope="module")
def reviews() -> dict:
    return {name: review_dive(Path(FOLDER) / name).metrics for name in LOGS}


def dataflash_truth(path: Path) -> dict:
    """Read with DFReader alone: ArduSub's deepest altitude, the armed seconds (a log that begins armed: its first
    arming event a disarm, or none and LOG_DISARMED 0), the rangefinder's good downward readings."""
    reader = DFReader.DFReader_binary(str(path))
    first = None
    events, good, altitude, written_disarmed = [], [], [], 0.0
    while (r := reader.recv_match(type=["ARM", "EV", "PARM", "CTUN", "RFND", "ATT"])) is not None:
        kind = r.get_type()
        first = r.TimeUS if first is None else first
        if kind == "ARM":
            events.append((r.TimeUS, bool(r.ArmState)))
        elif kind == "EV" and r.Id in ARM_EVENTS:
            events.append((r.TimeUS, ARM_EVENTS[r.Id]))
        elif kind == "PARM" and r.Name == "LOG_DISARMED":
            written_disarmed = r.Value
        elif kind == "CTUN":
            altitude.append(r.Alt)
        elif kind == "RFND" and getattr(r, "Stat", GOOD) == GOOD and getattr(r, "Orient", DOWN) == DOWN:
            good.append(r.Dist)
    events = sorted(set(events))
    armed_from = first if (not events[0][1] if events else not written_disarmed) else None
    armed = 0.0
    for t, state in events:
        if state and armed_from is None:
            armed_from = t
        elif not state and armed_from is not None:
            armed, armed_from = armed + (t - armed_from) * 1e-6, None
    return {"depth_max": -min(altitude) if altitude else None, "armed_s": armed, "range": good}


def telemetry_truth(path: Path) -> dict:
    """Read with mavutil alone: ArduSub's deepest relative_alt, armed seconds from the vehicle's HEARTBEATs, and the
    packets whose CRC does not check against pymavlink's definitions."""
    conn = mavutil.mavlink_connection(str(path), robust_parsing=True)
    altitude, armed, since, unchecked = [], 0.0, None, 0
    while (m := conn.recv_msg()) is not None:
        if m.get_type() == "BAD_DATA":
            unchecked += m.reason.startswith("invalid MAVLink CRC")
            continue
        if (m.get_srcSystem(), m.get_srcComponent()) != (1, 1) or m.get_type() not in ("HEARTBEAT",
                                                                                      "GLOBAL_POSITION_INT"):
            continue
        if m.get_type() == "GLOBAL_POSITION_INT":
            altitude.append(m.relative_alt / 1000.0)
        elif m.base_mode & 128 and since is None:
            since = m._timestamp
        elif not m.base_mode & 128 and since is not None:
            armed, since = armed + m._timestamp - since, None
    return {"depth_max": -min(altitude) if altitude else None, "armed_s": armed, "range": None,
            "unchecked": unchecked}


def truth(name: str) -> dict:
    path = Path(FOLDER) / name
    return dataflash_truth(path) if name.endswith(".BIN") else telemetry_truth(path)


def armed_seconds(metrics: dict) -> float:
    """The review's armed time, from its mode events ("armed ..." to "disarmed ...")."""
    total, since = 0.0, None
    for event in metrics["modes"]:
        if event["event"].startswith("armed") and since is None:
            since = event["t"]
        elif event["event"].startswith("disarmed") and since is not None:
            total, since = total + event["t"] - since, None
    assert since is None, "the review ends armed with no disarm: every corpus log ends disarmed"
    return total


@pytest.mark.parametrize("name", LOGS)
def test_every_log_reviewed_against_pymavlinks_own_reading(reviews, name):
    metrics, expected = reviews[name], truth(name)
    assert armed_seconds(metrics) == pytest.approx(expected["armed_s"], abs=0.6), metrics["modes"]
    depth = metrics.get("sensors", {}).get("depth")
    if expected["depth_max"] is not None and expected["depth_max"] > DIVE:
        assert depth is not None and depth["max_m"] == pytest.approx(expected["depth_max"], abs=0.15), depth
    assert not [e for e in metrics["modes"] if re.search(r"mode \d+", e["event"])], "a mode left as a number"
    if expected["range"] is not None:
        sensed = metrics.get("sensors", {}).get("rangefinder")
        if expected["range"]:
            assert sensed["samples"] == len(expected["range"])
            assert (sensed["min_m"], sensed["max_m"]) == pytest.approx((min(expected["range"]),
                                                                        max(expected["range"])))
        else:
            assert sensed is None
    read = metrics["source"]["tlog"]
    if name.endswith(".BIN"):
        assert read["complete"] and not read["damaged_bytes"], read      # a power-off's last bytes are not damage
        assert metrics["source"]["kind"] == "DataFlash log"
    else:   # every packet pymavlink's CRC refused is either of another definition version (a source none of whose
        # messages of that id decode: counted by source and id, not damage) or a damaged stretch
        unchecked = read["unchecked_messages"]
        assert sum(u["count"] for u in unchecked) + len(read["damaged_bytes"]) == expected["unchecked"], read
        assert not [u for u in unchecked if (u["sysid"], u["compid"]) == (1, 1)], unchecked


def test_the_modes_ardusub_added_are_named(reviews):
    events = {name: " ".join(e["event"] for e in m["modes"]) for name, m in reviews.items()}
    assert "MOTOR_DETECT" in events["mohai-2023-10-18-00000009.BIN"]
    assert "SURFTRAK" in events["mohai-2023-10-18-09-55-06-surftrak.tlog"]


def test_a_dive_without_the_bar30_is_deep_by_arduSubs_own_altitude_and_the_echo_sounder_is_read(reviews):
    """The SURFTRAK dive: no SCALED_PRESSURE2, ArduSub's own altitude says the depth; the echo sounder's readings
    come from BlueOS's sonar service (component 194 of the vehicle), 6.5 to 10.6 m above the bottom."""
    sensors = reviews["mohai-2023-10-18-09-55-06-surftrak.tlog"]["sensors"]
    assert sensors["depth"]["source"].startswith("ArduSub's own altitude") and 2.9 < sensors["depth"]["max_m"] < 3.1
    assert sensors["rangefinder"]["samples"] == 5908
    assert 6.4 < sensors["rangefinder"]["min_m"] < sensors["rangefinder"]["max_m"] < 10.7


def test_the_dataflash_and_telemetry_logs_of_one_dive_agree(reviews):
    """mohai-2023-10-18-00000016.BIN and mohai-2023-10-18-10-44-55.tlog: one dive, logged on board at 10 Hz and on
    the topside: the deepest point within 5 cm, the armed time within 1 s. (Their attitude statistics cover each
    log's whole span, which differ: the vehicle handled out of the water before the topside log began.)"""
    dataflash, telemetry = reviews["mohai-2023-10-18-00000016.BIN"], reviews["mohai-2023-10-18-10-44-55.tlog"]
    assert dataflash["sensors"]["depth"]["max_m"] == pytest.approx(telemetry["sensors"]["depth"]["max_m"], abs=0.05)
    assert armed_seconds(dataflash) == pytest.approx(armed_seconds(telemetry), abs=1.0)


# ArduSub's version and frame as MANIFEST.md states them (read there with pymavlink alone)
IDENTITY = {
    "small.BIN": ("4.1.0", 1), "mohai-2023-10-18-00000009.BIN": ("4.1.0", 1),
    "mohai-2023-10-18-00000016.BIN": ("4.2.0-dev", 1), "crews-quarters-2024-03-21-00000097.BIN": ("4.6.0-dev", 2),
    "west-seattle-2024-04-05-00000124.BIN": ("4.5.0-beta1", 2), "beckett-2023-05-17-old5.BIN": ("4.1.1", 1),
}


@pytest.mark.parametrize("name", sorted(IDENTITY))
def test_the_firmware_and_the_frame_are_named(reviews, name):
    version, config = IDENTITY[name]
    vehicle = reviews[name]["vehicle"]
    assert vehicle["firmware"] is not None and vehicle["firmware"].startswith(version), vehicle
    assert vehicle["frame"].startswith(f"FRAME_CONFIG {config} ("), vehicle


def test_arduSubs_own_control_measured_alike_from_the_on_board_targets_and_the_telemetry(reviews):
    """The same dive's ALT_HOLD and STABILIZE, measured on board (CTUN DAlt - Alt, ATT's targets, 10 Hz) and on the
    topside (NAV_CONTROLLER_OUTPUT's alt_error and attitude targets against ATTITUDE): the same stretches within 0.5 s,
    depth RMS within 1 cm, roll and pitch RMS within 0.5 deg (the two logs sample at different instants)."""
    dataflash = reviews["mohai-2023-10-18-00000016.BIN"]["ardusub_tracking"]
    telemetry = reviews["mohai-2023-10-18-10-44-55.tlog"]["ardusub_tracking"]
    assert [s["mode"] for s in dataflash] == [s["mode"] for s in telemetry] == ["STABILIZE", "ALT_HOLD", "ALT_HOLD"]
    for onboard, topside in zip(dataflash, telemetry):
        assert (onboard["from_s"], onboard["to_s"]) == pytest.approx((topside["from_s"], topside["to_s"]), abs=0.5)
        only_on_board = {"vertical_velocity_mps"}          # PSCD: the telemetry has no velocity target
        assert set(onboard["errors"]) - only_on_board == set(topside["errors"])
        for name, tolerance in (("depth_m", 0.01), ("roll_deg", 0.5), ("pitch_deg", 0.5)):
            if name in onboard["errors"]:
                assert onboard["errors"][name]["rms"] == pytest.approx(topside["errors"][name]["rms"],
                                                                       abs=tolerance), (onboard, topside)


def test_arduSubs_depth_hold_figures_are_dfreaders_ctun_and_pscd_in_its_armed_alt_hold(reviews):
    """ALT_HOLD's depth error of 00000016.BIN as DFReader alone reads it: CTUN's DAlt - Alt, and the position
    controller's vertical velocity error, PSCD's TVD - VD, from each MODE 2 record to the next MODE record or the
    disarm."""
    reader = DFReader.DFReader_binary(str(Path(FOLDER) / "mohai-2023-10-18-00000016.BIN"))
    mode, armed = None, True                              # the log starts armed (no ARM-on record)
    stretches: list[dict[str, list[float]]] = []
    while (r := reader.recv_match(type=["MODE", "ARM", "CTUN", "PSCD"])) is not None:
        if r.get_type() == "MODE":
            mode = r.Mode
            if mode == 2 and armed:
                stretches.append({"depth_m": [], "vertical_velocity_mps": []})
        elif r.get_type() == "ARM":
            armed = bool(r.ArmState)
        elif mode == 2 and armed and stretches:
            name, error = ("depth_m", r.DAlt - r.Alt) if r.get_type() == "CTUN" else \
                ("vertical_velocity_mps", r.TVD - r.VD)
            stretches[-1][name].append(error)
    figures = [s["errors"] for s in reviews["mohai-2023-10-18-00000016.BIN"]["ardusub_tracking"]
               if s["mode"] == "ALT_HOLD"]
    assert len(figures) == len(stretches) == 2
    for figure, stretch in zip(figures, stretches):
        for name, errors in stretch.items():
            assert figure[name]["samples"] == pytest.approx(len(errors), abs=1)
            assert figure[name]["max"] == pytest.approx(max(abs(e) for e in errors), abs=1e-6)
            assert figure[name]["rms"] == pytest.approx(np.sqrt(np.mean(np.square(errors))), rel=0.02)


def test_surftrak_flown_by_a_pilot_is_measured(reviews):
    stretches = reviews["mohai-2023-10-18-09-55-06-surftrak.tlog"]["ardusub_tracking"]
    surftrak = [s for s in stretches if s["mode"] == "SURFTRAK"]
    assert surftrak and all("depth_m" in s["errors"] for s in surftrak)
    assert not [s for s in stretches if s["mode"] == "MANUAL"]          # MANUAL holds no target


def test_identify_on_a_standard_frames_dive_refuses_the_heavy_prior_in_one_line(tmp_path, capsys):
    """mohai-2023-10-18-00000016.BIN is a standard BlueROV2's (FRAME_CONFIG 1, six thrusters): its RCOU outputs are
    not the Heavy's eight thrusters, so the shipped Heavy cannot be the prior; nothing is written."""
    out = tmp_path / "identified.yaml"
    code = cli.main(["identify", str(Path(FOLDER) / "mohai-2023-10-18-00000016.BIN"), "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and not out.exists()
    assert err.count("\n") == 1 and "FRAME_CONFIG 1 (VECTORED, 6 motors)" in err and "FRAME_CONFIG 2" in err, err
    assert "give --vehicle bluerov2)" in err


def test_identify_on_a_pilots_dive_fits_what_it_moved_and_never_writes_a_vehicle_worse_than_its_prior(tmp_path,
                                                                                                     capsys):
    """The 2.5 m pilot's dive of a standard BlueROV2 (no DVL, no mission) with the shipped bluerov2 as the prior: surge
    and sway are not fitted (the EKF has no horizontal velocity of its own), heave and yaw are (the dive went to
    2.46 m and turned); the six motors are read from SERVO1-6 with MOT_k_DIRECTION. Whatever the fit, the check's
    own figures decide: a vehicle is written only if it predicts depth and heading 1 s ahead on the held-back blocks
    no worse than the prior and is possible; else nothing is written and one line says why."""
    from rov_mav.commands.identify import _checked, _dofs, load_dataflash_run
    from rov_mav.model.vehicle import load_vehicle
    from rov_mav.offline.identify.identification import identify
    from rov_mav.offline.identify.prediction_check import DECIDING, impossible
    from rov_mav.shipped import listing

    path = str(Path(FOLDER) / "mohai-2023-10-18-00000016.BIN")
    prior = load_vehicle(next(s.path for s in listing("vehicle") if s.name == "bluerov2"))
    run, excited = load_dataflash_run(path, None, None, prior)
    assert [e.fitted for e in excited] == [False, False, True, True, True, True]
    assert run.pwm.shape[1] == 6 and 175.0 < run.t[-1] - run.t[0] < 185.0        # 180.5 s armed (MANIFEST)
    result = identify([run], prior, dofs=_dofs([excited]))
    assert impossible(result.vehicle) is None
    assert all(e.value == e.prior for e in result.estimates if e.name.endswith((".surge", ".sway")))
    worse = any(c.worse for c in _checked([run], prior, None, 0.4, _dofs([excited])) if c.quantity in DECIDING)

    out = tmp_path / "identified.yaml"
    code = cli.main(["identify", path, "--vehicle", "bluerov2", "--out", str(out)])
    printed = capsys.readouterr()
    assert "surge  kept: no horizontal velocity in the log" in printed.out
    if worse:
        assert code == 1 and not out.exists() and printed.err.count("\n") == 1
        assert "predicts worse than the prior on the held-back blocks" in printed.err
    else:
        assert code == 0 and load_vehicle(out).frame.config == 1


def test_the_summary_says_where_time_starts_and_what_the_log_began_in(capsys, tmp_path):
    """A pilot's telemetry log that begins 206 s before the arming reads so, not as "-206.0 s disarmed"."""
    assert cli.main(["analyze", str(Path(FOLDER) / "small.tlog"), "--out", str(tmp_path), "--rerun", "off"]) == 0
    line = next(line for line in capsys.readouterr().out.splitlines() if line.startswith("  modes"))
    assert line.startswith("  modes (t = 0: the first arming): -206.0 s log starts disarmed, MANUAL; 0.0 s armed"), line


def test_arduSubs_errors_to_its_targets_are_recorded_and_drawn_where_its_modes_held_them(tmp_path, capsys):
    """The pilot's dive reviewed with its recording: ArduSub's depth error in the recording exactly where ALT_HOLD
    held a depth (the metrics' stretches), and its timeline figure drawn."""
    out = tmp_path / "review"
    assert cli.main(["analyze", str(Path(FOLDER) / "mohai-2023-10-18-00000016.BIN"), "--out", str(out), "--rerun",
                     f"save:{out / 'dive.rrd'}"]) == 0
    metrics = json.loads((out / "metrics.json").read_text())
    held = [s for s in metrics["ardusub_tracking"] if "depth_m" in s["errors"]]
    t, values = read_column(out / "dive.rrd", "ardusub/error/depth_m", "Scalars:scalars")
    assert t.size == sum(s["errors"]["depth_m"]["samples"] for s in held)
    assert all(any(s["from_s"] - 1e-6 <= ti <= s["to_s"] for s in held) for ti in t)
    depth = np.abs(np.array([v[0] for v in values]))
    assert depth.max() == pytest.approx(max(s["errors"]["depth_m"]["max"] for s in held), rel=1e-6)
    assert (out / "timeline.png").stat().st_size > 0


def test_what_only_the_dataflash_log_holds_is_dfreaders_reading_of_it(reviews):
    """The EKF's innovation test ratios and the motors' limits of the pilot's dive, as DFReader alone reads them."""
    reader = DFReader.DFReader_binary(str(Path(FOLDER) / "mohai-2023-10-18-00000016.BIN"))
    compass, height, lift, rejected = [], [], [], 0
    while (r := reader.recv_match(type=["XKF4", "MOTB"])) is not None:
        if r.get_type() == "XKF4" and r.C == 0:
            compass.append(r.SM)
            height.append(r.SH)
        elif r.get_type() == "MOTB":
            lift.append(r.LiftMax)
    onboard = reviews["mohai-2023-10-18-00000016.BIN"]["onboard"]
    assert onboard["ekf"]["test_ratio_max"]["compass"] == pytest.approx(max(compass))
    assert onboard["ekf"]["rejected_share"]["compass"] == pytest.approx(sum(v > 1 for v in compass) / len(compass))
    assert onboard["ekf"]["test_ratio_max"]["height"] == pytest.approx(max(height))
    assert onboard["motors"]["lift_max_min"] == pytest.approx(min(lift)) and onboard["motors"]["samples"] == len(lift)
    assert "onboard" not in reviews["mohai-2023-10-18-10-44-55.tlog"]      # a telemetry log holds none of it


def test_the_surftrak_dives_bottom_is_rebuilt_as_an_independent_reader_sees_it(tmp_path):
    """tools/seafloor_from_log.py on the real SURFTRAK dive: its profile is the depth (ArduSub's own altitude) plus
    the sounder's range, laid along a line at 0.2 m/s of the time since the first sounding, the median in each 0.2 m;
    held against the same figures computed from pymavlink's own reading of the file, and flyable by the built-in
    vehicle (the environment file loads)."""
    import sys
    import yaml

    from rov_mav.model.environment import load_environment
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tools"))
    import seafloor_from_log

    log = Path(FOLDER) / "mohai-2023-10-18-09-55-06-surftrak.tlog"
    out = tmp_path / "env.yaml"
    assert seafloor_from_log.main([str(log), "--out", str(out), "--speed", "0.2", "--spacing", "0.2"]) == 0
    profile = np.array(yaml.safe_load(out.read_text())["environment"]["seafloor"]["profile"])
    assert load_environment(out).seafloor.depth_at(10.0, 0.0) == pytest.approx(np.interp(10.0, *profile.T))
    m = mavutil.mavlink_connection(str(log), robust_parsing=True)
    depth_t, depth, range_t, distance = [], [], [], []
    while (msg := m.recv_match(type=["GLOBAL_POSITION_INT", "DISTANCE_SENSOR"])) is not None:
        if msg.get_type() == "GLOBAL_POSITION_INT" and msg.get_srcComponent() == 1:
            depth_t.append(msg._timestamp)
            depth.append(-msg.relative_alt / 1000.0)
        elif msg.get_type() == "DISTANCE_SENSOR" and msg.orientation == 25 and msg.signal_quality != 1:
            range_t.append(msg._timestamp)
            distance.append(msg.current_distance / 100.0)
    range_t = np.array(range_t)
    bottom = np.interp(range_t, depth_t, depth) + np.array(distance)
    along = np.floor(0.2 * (range_t - range_t[0]) / 0.2).astype(int)
    expected = {k * 0.2: float(np.median(bottom[along == k])) for k in np.unique(along)}
    assert len(profile) == len(expected) and profile[-1, 0] == pytest.approx(0.2 * (range_t[-1] - range_t[0]), abs=0.2)
    theirs = np.array([expected[k] for k in sorted(expected)])
    assert np.abs(profile[:, 1] - theirs).max() < 0.01
    assert 7.0 < profile[:, 1].min() < profile[:, 1].max() < 10.7


@pytest.mark.parametrize("name", [n for n in LOGS if n.endswith(".tlog")])
def test_the_rangefinder_is_the_down_looking_sounders_good_readings_as_pymavlink_reads_them(reviews, name):
    """Every DISTANCE_SENSOR facing down within its range and not flagged invalid, from the vehicle's system; the
    autopilot's RANGEFINDER (a copy of the same sounder, without its status) is not counted beside them
    (mohai-2023-10-18-10-44-55.tlog holds both: counted together they were 670 readings too many)."""
    m = mavutil.mavlink_connection(str(Path(FOLDER) / name), robust_parsing=True)
    good = 0
    while (msg := m.recv_match(type="DISTANCE_SENSOR")) is not None:
        good += (msg.get_srcSystem() == 1 and msg.orientation == 25 and msg.signal_quality != 1
                 and msg.min_distance <= msg.current_distance <= msg.max_distance)
    rangefinder = reviews[name]["sensors"].get("rangefinder")
    assert (rangefinder["samples"] if rangefinder else 0) == good
