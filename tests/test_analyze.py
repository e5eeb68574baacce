"""`rov-mav analyze` reviews dives after the fact: a run's own log (its metrics must agree with the run's), its
telemetry log alone, a pilot's dive recorded by MAVProxy (a run we did not fly), ArduSub SITL flying its own mission
in AUTO, and truncated, damaged and unreadable logs (read as far as they go, or refused in one line)."""

from __future__ import annotations

import json
import math
import os
import struct
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

os.environ["MAVLINK20"] = "1"
from pymavlink import mavutil  # noqa: E402
from run_helpers import ROV_MAV, SPEEDUP, RunnerProcess, short_mission  # noqa: E402
from sitl_helpers import Sitl  # noqa: E402
from telemetry_helpers import read_column, temporal_entities  # noqa: E402
from bridge_helpers import MAVPROXY, Console  # noqa: E402
from bridge_helpers import BridgeProcess  # noqa: E402

from rov_mav.flight.record.runlog import DOF, REPORTED, parse_mission_start  # noqa: E402
from rov_mav.mission import metrics as tracking  # noqa: E402
from rov_mav.mission.missions import load_mission  # noqa: E402
from rov_mav.review.dive_review import review_dive  # noqa: E402
from rov_mav.review.logdir import read_run_folder  # noqa: E402
from rov_mav.review.reference import path_deviation  # noqa: E402

ANALYZE_WAIT = 300.0           # wall s for one analysis on a loaded machine
RUN_METRICS = ("duration_s", "rms_position_error_m", "max_position_error_m", "rms_attitude_error_rad",
               "rms_position_error_steady_m", "rms_attitude_error_steady_rad", "control_effort")


def analyze(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([ROV_MAV, "analyze", *args], capture_output=True, text=True, timeout=ANALYZE_WAIT,
                          stdin=subprocess.DEVNULL)


def records(path: Path) -> list[tuple[int, int, str]]:
    """(start, end, type) of every record of a tlog, as pymavlink reads it."""
    conn = mavutil.mavlink_connection(str(path))
    out, start = [], 0
    while (msg := conn.recv_msg()) is not None:
        out.append((start, conn.f.tell(), msg.get_type()))
        start = conn.f.tell()
    conn.close()
    return out


def end_of_record_at_mission_time(path: Path, fraction: float, duration: float) -> int:
    """The end (byte) of the first ATTITUDE record `fraction` of the way through the announced mission."""
    conn = mavutil.mavlink_connection(str(path))
    t0 = None
    try:
        while (msg := conn.recv_msg()) is not None:
            if msg.get_type() == "STATUSTEXT" and (announced := parse_mission_start(msg.text)) is not None:
                t0 = announced
            elif msg.get_type() == "ATTITUDE" and t0 is not None and msg.time_boot_ms / 1000 >= t0 + fraction * duration:
                return conn.f.tell()
    finally:
        conn.close()
    raise AssertionError(f"no ATTITUDE {fraction:.0%} into the mission in {path}")


@pytest.fixture(scope="module")
def own_run(tmp_path_factory):
    """A short mission flown by `rov-mav run --log` against the built-in vehicle: (log folder, its metrics, the
    mission file)."""
    workdir = tmp_path_factory.mktemp("own-run")
    mission = short_mission(workdir, goto_x=2.0, hold=3.0)
    log, metrics = workdir / "log", workdir / "metrics.json"
    with RunnerProcess(str(mission), "--speedup", str(SPEEDUP), "--log", str(log), "--metrics", str(metrics),
                       "--rerun", "off") as run:
        assert run.wait() == 0, run.output
    return log, json.loads(metrics.read_text()), mission


# -- our own logs --------------------------------------------------------------------------------------------

@pytest.mark.process
def test_a_runs_log_folder_gives_the_runs_own_metrics(own_run, tmp_path):
    log, run_metrics, _ = own_run
    out = tmp_path / "review"
    r = analyze(str(log), "--out", str(out), "--rerun", f"save:{out / 'dive.rrd'}")
    assert r.returncode == 0, r.stdout + r.stderr
    m = json.loads((out / "metrics.json").read_text())
    # ticks.csv keeps 9 significant digits: a position of metres to ~1e-8 m, so an error of millimetres read back
    # from it agrees to about 1e-8 absolute, not 1e-6 relative.
    for key in RUN_METRICS:
        assert m[key] == pytest.approx(run_metrics[key], rel=1e-6, abs=1e-7), key
    assert m["final_disturbance_estimate"] == pytest.approx(run_metrics["final_disturbance_estimate"], abs=1e-6)
    assert (m["mission"], m["controller"], m["completed"]) == ("short", "fuzzy", True)
    assert m["true_disturbance"] == run_metrics["true_disturbance"]
    assert m["loop"]["ticks"] == run_metrics["loop"]["ticks"]
    for key in ("control_rate_hz", "latency_p50_ms", "latency_p99_ms"):
        assert m["loop"][key] == pytest.approx(run_metrics["loop"][key], rel=1e-6), key
    # The telemetry log placed on the ticks' time: the run announced its mission's start, armed before it (the
    # lead-in) and disarmed after its end.
    assert m["reference"]["mission_start_from"] == "announced by the rov-mav run on the link"
    events = {e["event"]: e["t"] for e in m["modes"]}
    assert events["armed (MANUAL)"] < 0.0 < m["duration_s"] <= events["disarmed (MANUAL)"]
    # one override a tick, each sent just after its tick's state: the last tick's lands after the ticks' window
    assert m["commands"][0]["sysid"] == 255 and m["commands"][0]["count"] >= m["loop"]["ticks"] - 1, (
        m["commands"], m["loop"])
    assert m["telemetry"]["rate_hz"] == pytest.approx(50.0, rel=0.05)      # what the runner asked for
    assert m["battery"]["consumed_mah"] > 0 and m["battery"]["min_v"] <= m["battery"]["start_v"]
    assert m["saturation"]["outputs"]["samples"] > 0
    figures = {p.name for p in out.glob("*.png")}
    assert figures == {"dofs.png", "path3d.png", "estimates.png", "rates.png", "thrusters.png", "timeline.png"}
    t, _ = read_column(out / "dive.rrd", "pose/x", "Scalars:scalars")
    assert t.size == m["loop"]["ticks"]                                 # one row per tick, as a live recording
    assert "tracking: position RMS" in r.stdout and "battery:" in r.stdout
    assert "  modes (t = 0: announced by the rov-mav run on the link): " in r.stdout
    # The run's figures under the names ArduSub's are measured by: depth and horizontal errors split the position
    # error (their mean squares add up to its), and the three angles' to the attitude error's
    peer = m["rov_mav_tracking"]["errors"]
    assert peer["depth_m"]["rms"] ** 2 + peer["horizontal_m"]["rms"] ** 2 == pytest.approx(
        m["rms_position_error_m"] ** 2, rel=1e-6)
    assert sum(math.radians(peer[f"{a}_deg"]["rms"]) ** 2 for a in ("roll", "pitch", "yaw")) == pytest.approx(
        m["rms_attitude_error_rad"] ** 2, rel=1e-6)
    assert "rov-mav's control" in r.stdout


@pytest.mark.process
def test_a_runs_telemetry_log_alone_against_its_mission(own_run):
    log, run_metrics, mission = own_run
    planned = load_mission(mission)
    review = review_dive(log / "mavlink.tlog", planned)
    m = review.metrics
    assert not review.warnings
    assert m["reference"]["kind"] == "mission"
    assert m["reference"]["mission_start_from"] == "announced by the rov-mav run on the link"
    # From the mission's start to the first state at or after its end.
    assert m["completed"] and m["duration_s"] == pytest.approx(planned.duration, abs=0.05)
    # Every state the vehicle sent, where the run ticked once per batch it read (on the newest attitude and
    # position of the batch): the same tracking of the vehicle's own estimate (the run's ticks keep it beside the
    # position its law flew on, the estimate blended) within the spread of a few samples.
    ticks = read_run_folder(log).ticks
    flown = ticks["t"] >= 0.0
    eta_d = np.column_stack([ticks[f"{d}_d"][flown] for d in DOF])
    vehicle = np.column_stack([*(ticks[c][flown] for c in REPORTED), eta_d[:, 3:]])
    still = np.zeros((int(flown.sum()), 6))
    as_ticked = tracking.run_metrics("short", "fuzzy", ticks["t"][flown], vehicle, eta_d, still, still, None, True)
    for key in ("rms_position_error_m", "max_position_error_m", "rms_position_error_steady_m"):
        assert m[key] == pytest.approx(as_ticked[key], rel=0.3, abs=1e-3), key
    assert m["control_effort"] is None and m["final_disturbance_estimate"] is None   # not in a telemetry log
    assert "thruster PWMs (RCIN passthrough)" in m["loop"]["source"]
    assert m["loop"]["latency_p50_ms"] > 0
    assert m["saturation"]["commands"]["samples"] > run_metrics["loop"]["ticks"]


# -- a dive we did not fly -----------------------------------------------------------------------------------

@pytest.mark.process
def test_a_pilots_dive_recorded_by_mavproxy(tmp_path):
    """MAVProxy drives the built-in vehicle in MANUAL with RC overrides (real time: its heartbeat is 1 Hz of wall
    time) and records the telemetry log: full throttle down for 2 s (the four vertical thrusters at their limit),
    then yaw right for 2 s."""
    tlog = tmp_path / "pilot.tlog"
    with BridgeProcess(tmp_path, "--start-depth", "2", speedup=1.0) as bridge:
        console = Console([MAVPROXY, f"--master=udpout:127.0.0.1:{bridge.port}", f"--state-basedir={tmp_path}",
                           f"--logfile={tlog}"], tmp_path / "mavproxy.out", tmp_path)
        try:
            console.expect("Detected vehicle 1:1")
            console.expect("Mode MANUAL")
            console.send("rc all 1500")
            console.send("arm throttle")
            console.expect("ARMED")
            time.sleep(1.0)
            console.send("rc 3 1100")
            time.sleep(2.0)
            console.send("rc 3 1500")
            console.send("rc 4 1600")
            time.sleep(2.0)
            console.send("rc 4 1500")
            time.sleep(1.0)
            console.send("disarm")
            console.expect("DISARMED")
            time.sleep(1.5)                   # MAVProxy writes its log from a queue
        finally:
            console.close("exit")
    out = tmp_path / "review"
    r = analyze(str(tlog), "--out", str(out), "--rerun", f"save:{out / 'dive.rrd'}")
    assert r.returncode == 0, r.stdout + r.stderr
    m = json.loads((out / "metrics.json").read_text())
    assert m["reference"]["kind"] == "none" and m["reference"]["time_zero_from"] == "the first arming"
    assert [e["event"] for e in m["modes"]][-2:] == ["armed (MANUAL)", "disarmed (MANUAL)"]
    armed_for = m["modes"][-1]["t"]
    # The vertical thrusters (5-8) sat at their limit for the 2 s of full throttle, the horizontal ones never.
    at_limit = m["saturation"]["outputs"]["fraction_at_limit"]
    assert at_limit[:4] == [0.0] * 4
    assert at_limit[4:] == pytest.approx([2.0 / armed_for] * 4, abs=0.12)
    assert "commands" not in m["saturation"]          # the overrides were a pilot's inputs, not thruster PWMs
    (station,) = m["commands"]
    assert (station["sysid"], station["message"]) == (255, "RC_CHANNELS_OVERRIDE")
    assert station["rate_hz"] == pytest.approx(10.0, rel=0.3)   # MAVProxy's rc module: override_hz 10
    assert m["battery"]["min_v"] < m["battery"]["start_v"] - 0.3      # four thrusters at full power sag it
    # Physics seen through the decoded state: deeper while the vertical thrusters pushed, turning while yawing.
    review = review_dive(tlog)
    t, z, psi = review.trace.t, review.trace.eta[:, 2], np.unwrap(review.trace.eta[:, 5])
    servo_t, servo = review.thrusters["outputs (SERVO_OUTPUT_RAW)"]
    pushed = servo_t[np.all(np.abs(servo[:, 4:] - 1500) >= 398, axis=1)]
    assert pushed.size and pushed.max() - pushed.min() == pytest.approx(2.0, abs=0.7)
    before, after = np.interp([pushed.min(), pushed.max() + 0.5], t, z)
    assert after - before > 0.3
    assert psi[-1] - np.interp(pushed.max(), t, psi) > 0.2
    assert m["loop"]["latency_p50_ms"] is None
    # The recording: every state on the vehicle's timeline, no reference or controller internals to show.
    assert read_column(out / "dive.rrd", "pose/z", "Scalars:scalars")[0] == pytest.approx(t, abs=1e-6)
    assert not {"error/position", "disturbance/force", "control/force"} & temporal_entities(out / "dive.rrd")
    assert {p.name for p in out.glob("*.png")} == {"dofs.png", "path3d.png", "thrusters.png", "timeline.png"}


@pytest.mark.process
def test_ardusub_flying_its_own_mission_in_auto(tmp_path):
    """ArduSub SITL flies three waypoints at 2 m in AUTO, uploaded and recorded by MAVProxy: the review finds the
    mission in the log and measures the path against where ArduSub steers."""
    lat, lon = 33.810313, -118.393867
    north, east = 4.0 / 111_319.49, 4.0 / (111_319.49 * math.cos(math.radians(lat)))
    mission = tmp_path / "mission.txt"
    items = [(0, 0, lat, lon, 0.0)] + [(i, 3, la, lo, -2.0) for i, (la, lo) in
                                       enumerate([(lat, lon), (lat + north, lon), (lat + north, lon + east)], 1)]
    mission.write_text("QGC WPL 110\n" + "".join(f"{i}\t{int(i == 0)}\t{frame}\t16\t0\t0\t0\t0\t{la:.8f}\t{lo:.8f}\t"
                                                 f"{alt}\t1\n" for i, frame, la, lo, alt in items))
    tlog = tmp_path / "auto.tlog"
    with Sitl(tmp_path / "sitl") as sitl:
        sitl.wait_for_port(sitl.port0)
        console = Console([MAVPROXY, f"--master={sitl.target}", f"--state-basedir={tmp_path}", f"--logfile={tlog}",
                           "--streamrate=10"], tmp_path / "mavproxy.out", tmp_path)
        try:
            console.expect("Detected vehicle", 60)
            console.send("set heartbeat 4")          # SITL runs faster than the wall: keep its GCS failsafe quiet
            console.poll(f"wp load {mission}", "Flight plan received", 60)
            console.poll("mode GUIDED", "Mode GUIDED", 120)  # accepted once the EKF has a position
            console.send("arm throttle")
            console.expect("ARMED", 30)
            console.send("mode AUTO")
            console.expect("Reached command #3", 180)
            console.send("disarm")
            console.expect("DISARMED", 30)
            time.sleep(1.5)
        finally:
            console.close("exit")
    r = analyze(str(tlog), "--out", str(tmp_path / "review"), "--rerun", "off")
    assert r.returncode == 0, r.stdout + r.stderr
    m = json.loads((tmp_path / "review" / "metrics.json").read_text())
    assert m["reference"]["kind"] == "waypoints"
    p = m["path"]
    # Where ArduSub put them: north/east around the EKF origin (within the tangent plane's 0.4 % and MAVProxy's
    # 1e-7 degree), 2 m below home.
    waypoints = np.array(p["waypoints"])
    home_down = waypoints[:, 2] - 2.0
    assert waypoints[:, :2].ravel() == pytest.approx([0, 0, 4, 0, 4, 4], abs=0.05)
    assert np.ptp(home_down) == 0 and abs(home_down[0]) < 0.6
    assert p["samples_from"] == "AUTO"
    assert max(p["closest_approach_m"]) < 0.5 and p["rms_cross_track_m"] < 0.5
    assert any(e["event"] == "mode AUTO" for e in m["modes"])


# -- damaged logs --------------------------------------------------------------------------------------------

@pytest.mark.process
def test_a_truncated_telemetry_log_is_read_as_far_as_it_goes(own_run, tmp_path):
    log, run_metrics, mission = own_run
    data = (log / "mavlink.tlog").read_bytes()
    last_whole = end_of_record_at_mission_time(log / "mavlink.tlog", 0.6, load_mission(mission).duration)
    cut = last_whole + 8 + 3                          # into the next record's packet header
    (tmp_path / "cut.tlog").write_bytes(data[:cut])
    r = analyze(str(tmp_path / "cut.tlog"), "--mission", str(mission), "--out", str(tmp_path / "review"),
                "--rerun", "off")
    assert r.returncode == 0, r.stdout + r.stderr
    (warning,) = [line for line in r.stderr.splitlines() if "warning" in line]
    assert f"STOPPED at byte {last_whole}: the last 11 bytes are not a whole record" in warning
    last_good = float(warning.split("last good record at t = ")[1].split(" s")[0])
    m = json.loads((tmp_path / "review" / "metrics.json").read_text())
    assert m["source"]["tlog"]["read_up_to_byte"] == last_whole and not m["source"]["tlog"]["complete"]
    assert not m["completed"] and m["duration_s"] == pytest.approx(last_good, abs=0.1)
    assert m["duration_s"] < run_metrics["duration_s"]


@pytest.mark.process
def test_a_truncated_ticks_file_stops_at_the_cut_row(own_run, tmp_path):
    log, _, _ = own_run
    folder = tmp_path / "log"
    folder.mkdir()
    for name in ("events.csv", "run.json", "mavlink.tlog"):
        (folder / name).write_bytes((log / name).read_bytes())
    ticks = (log / "ticks.csv").read_bytes()
    lines = ticks.splitlines(keepends=True)
    cut = sum(len(line) for line in lines[:101]) + 40           # header + 100 rows, then part of one
    (folder / "ticks.csv").write_bytes(ticks[:cut])
    review = review_dive(folder)
    assert any(f"read 100 ticks, STOPPED at line 102 (byte {cut - 40})" in w for w in review.warnings)
    assert review.metrics["loop"]["ticks"] == 100 and review.trace.t.size == 100


@pytest.mark.process
def test_a_damaged_telemetry_log_skips_the_damage_and_says_where(own_run, tmp_path):
    log, _, mission_file = own_run
    original = log / "mavlink.tlog"
    data = bytearray(original.read_bytes())
    rng = np.random.default_rng(7)
    attitude = [(a, b) for a, b, kind in records(original) if kind == "ATTITUDE"]
    chosen = sorted(rng.choice(len(attitude) - 2, 5, replace=False))
    flipped = []
    for k in chosen:                     # one bit in the payload of each of five packets: their CRC fails
        a, b = attitude[k]
        at = int(rng.integers(a + 8 + 10, b - 2))
        data[at] ^= 1 << int(rng.integers(8))
        flipped.append(at)
    stamp = next(a for k, (a, _) in enumerate(attitude) if k > len(attitude) // 2 and k not in chosen)
    data[stamp + 1] ^= 0x01              # a high bit of one record's timestamp: 9 years later
    (tmp_path / "flipped.tlog").write_bytes(bytes(data))
    r = analyze(str(tmp_path / "flipped.tlog"), "--mission", str(mission_file), "--out", str(tmp_path / "review"),
                "--rerun", "off")
    assert r.returncode == 0, r.stdout + r.stderr
    assert "damaged bytes skipped in 5 place(s)" in r.stderr and "1 damaged timestamp(s) replaced" in r.stderr
    m = json.loads((tmp_path / "review" / "metrics.json").read_text())
    tlog = m["source"]["tlog"]
    assert len(tlog["damaged_bytes"]) == 5 and all(a <= at < b for (a, b), at in zip(tlog["damaged_bytes"], flipped))
    assert tlog["timestamps_replaced"] == 1 and tlog["messages"] == len(records(original)) - 5
    mission = load_mission(mission_file)
    intact, damaged = review_dive(original, mission), review_dive(tmp_path / "flipped.tlog", mission)
    lost = intact.trace.t.size - damaged.trace.t.size               # five ATTITUDE lost, the rest decoded
    assert 1 <= lost <= 5
    assert np.all(np.diff(damaged.trace.t) > 0)                       # the bad timestamp left no trace in time
    assert m["completed"]
    # After a lost ATTITUDE the decoder (the runner's) pairs each position with the next period's attitude, as the
    # runner would live: the errors move by a few percent, not more.
    assert m["rms_position_error_m"] == pytest.approx(intact.metrics["rms_position_error_m"], rel=0.1)


@pytest.mark.parametrize("content,name,expected", [
    (b"", "empty.tlog", "no MAVLink message could be read"),
    (bytes(np.random.default_rng(1).integers(0, 256, 4000, dtype=np.uint8)), "noise.tlog", "not a telemetry log"),
    (b"\xa3\x95" * 100, "flight.bin", "no DataFlash record in its 200 bytes"),
    (b"", "flight.BIN", "empty: not a dataflash log"),
    (b"#!garbage\n" * 10, "flight.log", "a dataflash text log"),
])
@pytest.mark.process
def test_nothing_usable_is_one_line_and_exit_2(tmp_path, content, name, expected):
    (tmp_path / name).write_bytes(content)
    r = analyze(str(tmp_path / name), "--out", str(tmp_path / "review"), "--rerun", "off")
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and r.stderr.startswith("rov-mav analyze: error: ") and expected in r.stderr
    assert not (tmp_path / "review").exists()


@pytest.mark.process
def test_not_a_log_is_one_line_and_exit_2(tmp_path):
    (tmp_path / "somewhere").mkdir()
    for path in (tmp_path / "somewhere", tmp_path / "missing.tlog"):
        r = analyze(str(path), "--rerun", "off")
        assert r.returncode == 2 and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr, r.stderr


# -- pieces ----------------------------------------------------------------------------------------------------

def test_cross_track_error_is_the_distance_to_the_nearest_leg():
    path = np.array([[0.0, 0, 0], [4, 0, 0], [4, 4, 0]])
    points = np.array([[2.0, 1, 0], [5, 2, 0], [-1, 0, 0], [4, 6, 1], [3.5, 0.5, 0]])
    assert path_deviation(points, path) == pytest.approx([1.0, 1.0, 1.0, math.hypot(2, 1), 0.5])


@pytest.mark.process
def test_a_tlog_record_is_eight_bytes_of_time_then_the_packet(own_run):
    log, _, _ = own_run
    start, end, _ = records(log / "mavlink.tlog")[0]
    head = (log / "mavlink.tlog").read_bytes()[start:end]
    assert abs(struct.unpack(">Q", head[:8])[0] * 1e-6 - time.time()) < 3600 and head[8] in (0xFD, 0xFE)


# -- the vehicle's own log (DataFlash) --------------------------------------------------------------------------

@pytest.mark.process
def test_the_vehicles_dataflash_log_of_a_run_gives_its_metrics_and_a_cut_one_says_where_it_stopped(tmp_path):
    """A run against a bridge process writing its own .BIN (`--log-dir`): the run's log folder with the .BIN in place
    of mavlink.tlog is reviewed with the run's ticks and the vehicle's records placed by the announced start;
    `analyze FILE.BIN` finds the mission's start in the run's STATUSTEXT, logged as "GCS:..." in a MSG record, and
    measures the dive from the vehicle's 10 Hz XKF1 as the run measured it from its 50 Hz telemetry; a copy cut inside
    a record past 60 % is read as far as it goes."""
    mission = short_mission(tmp_path, goto_x=2.0, hold=3.0)
    bridge = BridgeProcess(tmp_path, "--log-dir", str(tmp_path / "logs"), "--start-depth", "1", speedup=5.0)
    metrics, run_log = tmp_path / "metrics.json", tmp_path / "runlog"
    with RunnerProcess("--target", f"udpout:127.0.0.1:{bridge.port}", str(mission), "--metrics", str(metrics),
                       "--log", str(run_log), "--heartbeat-timeout", "60", "--rerun", "off") as run, bridge:
        assert run.wait() == 0, run.output
    run_metrics = json.loads(metrics.read_text())
    [log] = sorted((tmp_path / "logs").glob("*.BIN"))
    (run_log / "mavlink.tlog").unlink()                   # the run's folder with the vehicle's log in its place
    (run_log / log.name).write_bytes(log.read_bytes())
    r = analyze(str(run_log), "--out", str(tmp_path / "mixed"), "--rerun", "off")
    assert r.returncode == 0, r.stdout + r.stderr
    mixed = json.loads((tmp_path / "mixed" / "metrics.json").read_text())
    assert mixed["rms_position_error_m"] == pytest.approx(run_metrics["rms_position_error_m"], abs=1e-7)   # 9 digits
    assert mixed["reference"]["mission_start_from"].startswith("announced"), mixed["reference"]
    depth = mixed["sensors"]["depth"]                        # the Bar30's BARO records, against BARO2_GND_PRESS
    assert depth["mean_m"] == pytest.approx(1.0, abs=0.05) and "BARO2_GND_PRESS" in depth["source"], depth
    assert math.isfinite(mixed["battery"]["start_v"]), mixed["battery"]    # from the vehicle's BAT records
    r = analyze(str(log), "--mission", str(mission), "--out", str(tmp_path / "review"), "--rerun", "off")
    assert r.returncode == 0, r.stdout + r.stderr
    m = json.loads((tmp_path / "review" / "metrics.json").read_text())
    assert m["completed"], r.stdout
    assert m["rms_position_error_m"] == pytest.approx(run_metrics["rms_position_error_m"], rel=0.5, abs=0.01)
    assert "announced by the rov-mav run" in r.stdout + r.stderr
    cut = tmp_path / "cut.BIN"
    data = log.read_bytes()
    inside = data.index(b"\xa3\x95", int(0.6 * len(data))) + 3     # 3 bytes into a record (its header and type)
    cut.write_bytes(data[:inside])                                  # (a cut on a record's boundary leaves none)
    r = analyze(str(cut), "--mission", str(mission), "--out", str(tmp_path / "cut-review"), "--rerun", "off")
    assert r.returncode == 0, r.stdout + r.stderr
    # a DataFlash log cut mid-record is what a power-off leaves: said so, not called damage; read up to the cut
    assert "bytes of an unfinished record (a power-off)" in r.stdout and "Traceback" not in r.stderr
    cut_metrics = json.loads((tmp_path / "cut-review" / "metrics.json").read_text())
    assert not cut_metrics["completed"]
    read = cut_metrics["source"]["tlog"]
    assert read["power_off_tail"] and 0 < read["bytes"] - read["read_up_to_byte"] < 256


@pytest.mark.process
def test_a_dive_without_a_position_source_is_reviewed_from_what_the_vehicle_has(tmp_path):
    """Most BlueROV2s have no DVL or acoustic positioning: a log with ATTITUDE, the Bar30 (SCALED_PRESSURE2), a
    downward rangefinder (DISTANCE_SENSOR), outputs and battery, and no LOCAL_POSITION_NED. analyze reviews the
    attitude, heading, depth, the distance above the bottom, the thrusters and the battery, with the figures these
    are known to be, and says there was no position (it once said "0 states" and drew the battery only)."""
    mav = mavutil.mavlink.MAVLink(None, 1, 1)
    depth_of = lambda k: min(k * 0.02, 4.0)                  # noqa: E731 - m: down at 0.2 m/s to 4 m, from 0
    packets = []
    for k in range(600):                                     # 60 s at 10 Hz
        ms, us = k * 100, int(1_700_000_000e6) + k * 100_000
        msgs = [mav.heartbeat_encode(mavutil.mavlink.MAV_TYPE_SUBMARINE, mavutil.mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA,
                                     209, 19, 4)] if k % 10 == 0 else []
        msgs += [mav.attitude_encode(ms, math.radians(3.0), math.radians(-4.0), math.radians(k * 0.1), 0, 0, 0),
                 mav.scaled_pressure2_encode(ms, 1013.25 + depth_of(k) * 1000 * 9.80665 / 100, 0.0, 1500),
                 mav.distance_sensor_encode(ms, 20, 5000, round(600 - 100 * depth_of(k)), 0, 1,
                                            mavutil.mavlink.MAV_SENSOR_ROTATION_PITCH_270, 0),
                 mav.sys_status_encode(0, 0, 0, 500, 16000 - k, 300, -1, 0, 0, 0, 0, 0, 0),
                 mav.servo_output_raw_encode(ms * 1000, 0, *([1550] * 8))]
        packets += [struct.pack(">Q", us) + m.pack(mav) for m in msgs]
    log = tmp_path / "pilot.tlog"
    log.write_bytes(b"".join(packets))
    r = analyze(str(log), "--out", str(tmp_path / "review"), "--rerun", f"save:{tmp_path / 'dive.rrd'}")
    assert r.returncode == 0, r.stdout + r.stderr
    sensors = json.loads((tmp_path / "review" / "metrics.json").read_text())["sensors"]
    attitude, depth, bottom = sensors["attitude"], sensors["depth"], sensors["rangefinder"]
    assert attitude["samples"] == 600 and attitude["roll_rms_deg"] == pytest.approx(3.0, abs=1e-3)
    assert attitude["pitch_rms_deg"] == pytest.approx(4.0, abs=1e-3)
    assert attitude["heading_end_deg"] == pytest.approx(59.9, abs=1e-3)
    assert depth["max_m"] == pytest.approx(4.0, abs=0.01) and depth["min_m"] == pytest.approx(0.0, abs=0.01)
    assert bottom["min_m"] == pytest.approx(2.0, abs=0.01) and bottom["max_m"] == pytest.approx(6.0, abs=0.01)
    assert "no position in the log" in r.stdout + r.stderr
    assert "depth: 0.00 to 4.00 m" in r.stdout and "above the bottom (rangefinder): 2.00 to 6.00 m" in r.stdout
    assert (tmp_path / "review" / "timeline.png").stat().st_size > 0 and (tmp_path / "dive.rrd").stat().st_size > 0
