"""The built-in vehicle's own log: DataFlash files written as ArduSub writes them, read back with pymavlink's own
DataFlash reader (DFReader), against the vehicle driven by a pymavlink station over real UDP."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
from pymavlink import DFReader
from bridge_helpers import BridgeThread, Gcs
from bridge_helpers import SPEEDUP

from rov_mav.review.dataflash_records import read_records
from rov_mav.review.dive_review import review_dive
from sim_bridge.onboard_log.dataflash import FORMATS, record

QUIET = {"FS_PILOT_INPUT": 0, "FS_GCS_ENABLE": 0}


def _messages(path) -> list:
    reader = DFReader.DFReader_binary(str(path))
    out = []
    while (m := reader.recv_msg()) is not None:
        out.append(m)
    return out


def _arm(gcs: Gcs, arm: bool) -> None:
    assert gcs.command(400, 1.0 if arm else 0.0).result == 0
    gcs.recv("HEARTBEAT", cond=lambda m: m.get_srcSystem() == 1 and bool(m.base_mode & 128) == arm)


@pytest.mark.process
def test_an_armed_dive_is_logged_as_ardusub_logs_it_and_pymavlink_reads_it(tmp_path):
    with BridgeThread(SPEEDUP, start_depth=2.0, params=QUIET, log_dir=str(tmp_path)) as b:
        gcs = Gcs(b.port, SPEEDUP)
        try:
            gcs.connect()
            assert not list(tmp_path.glob("*.BIN"))             # LOG_DISARMED 0: nothing before arming
            _arm(gcs, True)
            gcs.rc_override([1600, 1500, 1500, 1500, 1500, 1500, 1500, 1500])
            gcs.send("statustext", 6, b"rov-mav: mission t0 = 12.500 s since boot")
            time.sleep(0.5)
            _arm(gcs, False)
        finally:
            gcs.close()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["00000001.BIN", "LASTLOG.TXT"]
    assert (tmp_path / "LASTLOG.TXT").read_bytes() == b"1\r\n"
    messages = _messages(tmp_path / "00000001.BIN")
    kinds = {m.get_type() for m in messages}
    assert {"FMT", "PARM", "UNIT", "MULT", "FMTU", "MSG", "VER", "MODE", "ATT", "RATE", "RCIN", "RCOU", "CTUN",
            "BARO", "XKF1", "POS", "BAT"} <= kinds
    reader = DFReader.DFReader_binary(str(tmp_path / "00000001.BIN"))
    while reader.recv_msg() is not None:
        pass
    assert reader.mav_type == 12 and reader.flightmode == "MANUAL"          # from the firmware MSG and MODE
    assert reader.params["MAV_GCS_SYSID"] == 255 and reader.param_defaults["FS_PILOT_INPUT"] == 2
    texts = [m.Message for m in messages if m.get_type() == "MSG"]
    assert texts[0] == "ArduSub V4.7.2 (00000000)"
    assert "GCS:rov-mav: mission t0 = 12.500 s since boot" in texts          # a GCS's text, as handle_statustext
    xkf = [m for m in messages if m.get_type() == "XKF1"]
    assert all(m.PD == pytest.approx(2.0, abs=0.05) for m in xkf[:5])        # the estimate's depth, m
    assert xkf[0].fmt.get_unit("PD") == "m" and xkf[0].fmt.get_unit("TimeUS").endswith("s")
    times = [m.TimeUS for m in xkf]
    assert all(0.09e6 < b - a < 0.11e6 for a, b in zip(times, times[1:]))   # 10 Hz of vehicle time
    assert any(m.C1 == 1600 for m in messages if m.get_type() == "RCIN")   # the station's override, as input
    rcou = [m for m in messages if m.get_type() == "RCOU"]
    assert all(1100 <= getattr(m, f"C{i}") <= 1900 for m in rcou for i in range(1, 9))   # the mixer's motors
    assert len({tuple(getattr(m, f"C{i}") for i in range(5, 9)) for m in rcou}) > 1   # the vertical ones pitch


@pytest.mark.process
def test_a_new_file_per_arming_with_dsrmrot_and_per_boot_with_log_disarmed(tmp_path):
    rotate, per_boot = tmp_path / "rotate", tmp_path / "boot"
    with BridgeThread(SPEEDUP, params={**QUIET, "LOG_FILE_DSRMROT": 1}, log_dir=str(rotate)) as b:
        gcs = Gcs(b.port, SPEEDUP)
        try:
            gcs.connect()
            for _ in range(2):
                _arm(gcs, True)
                time.sleep(0.2)
                _arm(gcs, False)
        finally:
            gcs.close()
    assert sorted(p.name for p in rotate.glob("*.BIN")) == ["00000001.BIN", "00000002.BIN"]
    assert (rotate / "LASTLOG.TXT").read_bytes() == b"2\r\n"
    with BridgeThread(SPEEDUP, params={**QUIET, "LOG_DISARMED": 1}, log_dir=str(per_boot)) as b:
        gcs = Gcs(b.port, SPEEDUP)
        try:
            gcs.connect()
            time.sleep(0.3)
            assert gcs.command(246, 1).result == 0                               # reboot
            gcs.recv("STATUSTEXT", cond=lambda m: m.text == "ArduPilot Ready")
            time.sleep(0.3)
        finally:
            gcs.close()
    files = sorted(per_boot.glob("*.BIN"))
    assert [p.name for p in files] == ["00000001.BIN", "00000002.BIN"]
    first = _messages(files[0])
    assert {"ATT", "XKF1"} <= {m.get_type() for m in first}                  # logged while disarmed


def test_records_pack_as_their_format_says():
    att = record(FORMATS["ATT"], 123, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 3)
    assert att[:3] == b"\xa3\x95" + bytes([FORMATS["ATT"].type]) and len(att) == FORMATS["ATT"].length
    xkf = record(FORMATS["XKF1"], 1, 0, 12.34, -5.0, 359.99, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, math.nan)
    assert len(xkf) == FORMATS["XKF1"].length
    with pytest.raises(ValueError):
        record(FORMATS["ATT"], 1, 2)


def test_an_older_ardusub_log_is_read_through_its_own_formats(tmp_path):
    """ArduSub 4.0-era layouts (ATT in centidegrees with ErrRP/ErrYaw, EKF2's NKF1 without a core field, BAT
    without an instance, PARM without a default, EV for arming, RCOU's 14 channels), other type ids: the reader goes
    by each file's FMT records and the fields' labels."""
    from sim_bridge.onboard_log.dataflash import FMT, Format

    from rov_mav.review.dataflash_log import read_dataflash_dive
    from rov_mav.review.tlog import ReadReport

    old = {
        "PARM": Format(30, "PARM", "QNf", "TimeUS,Name,Value", "", ""),
        "MSG": Format(31, "MSG", "QZ", "TimeUS,Message", "", ""),
        "MODE": Format(32, "MODE", "QMBB", "TimeUS,Mode,ModeNum,Rsn", "", ""),
        "EV": Format(33, "EV", "QB", "TimeUS,Id", "", ""),
        "ATT": Format(34, "ATT", "QccccCCCCB", "TimeUS,DesRoll,Roll,DesPitch,Pitch,DesYaw,Yaw,ErrRP,ErrYaw,AEKF", "",
                      ""),
        "NKF1": Format(35, "NKF1", "QccCfffffffccce", "TimeUS,Roll,Pitch,Yaw,VN,VE,VD,dPD,PN,PE,PD,GX,GY,GZ,OH", "",
                       ""),
        "RCOU": Format(36, "RCOU", "Q" + "H" * 14, "TimeUS," + ",".join(f"C{i}" for i in range(1, 15)), "", ""),
        "BAT": Format(37, "BAT", "Qfffffcf", "TimeUS,Volt,VoltR,Curr,CurrTot,EnrgTot,Temp,Res", "", ""),
    }
    data = [record(FMT, f.type, f.length, f.name, f.format, f.labels) for f in (FMT, *old.values())]
    data += [record(old["PARM"], 1000, "MAV_GCS_SYSID", 255.0), record(old["MSG"], 1000, "ArduSub V4.0.3 (abc)"),
             record(old["MODE"], 1000, 19, 19, 0), record(old["EV"], 2000, 10)]
    for k in range(20):
        t = 1_000_000 + k * 100_000
        data += [record(old["ATT"], t, 0, 5.0, 0, -2.0, 90.0, 90.0, 0, 0, 1),
                 record(old["NKF1"], t, 5.0, -2.0, 90.0, 0.2, 0, 0, 0, 0.02 * k, 1.0, 2.0, 0, 0, 0, 0),
                 record(old["RCOU"], t, *([1500 + k] * 14)),
                 record(old["BAT"], t, 15.5, 15.5, 3.0, 120.0, 1.8, 25.0, 0.01)]
    data.append(record(old["EV"], 3_000_000, 11))
    path = tmp_path / "old.BIN"
    path.write_bytes(b"".join(data) + b"\xa3\x95")            # and a cut record at the end
    report = ReadReport(str(path), 0)
    dive = read_dataflash_dive(path, report)
    assert np.degrees(dive.attitude[0]) == pytest.approx((5.0, -2.0, 90.0), abs=0.01)   # centidegrees, by the letter
    assert dive.state_t.size == 20 and dive.eta[-1, 0] == pytest.approx(0.38) and dive.eta[-1, 2] == pytest.approx(2.0)
    assert dive.servo[-1].tolist() == [1519.0] * 8
    assert dive.armed.tolist() == [False, True, False] and dive.mode.tolist() == [19, 19, 19]   # MODE, EV 10, EV 11
    assert dive.voltage[0] == pytest.approx(15.5) and dive.current[0] == pytest.approx(3.0)
    assert dive.params == {"MAV_GCS_SYSID": 255.0} and dive.texts[0][3] == "ArduSub V4.0.3 (abc)"
    assert report.truncated and report.end == len(b"".join(data)) and report.messages == len(data)
    assert not report.damaged and report.power_off_tail                  # the cut record: a power-off's, not damage


@pytest.mark.process
def test_a_log_that_cannot_be_written_stops_with_one_line_and_the_vehicle_flies_on(tmp_path, capsys):
    """The log the arming opens is /dev/full, which takes no byte: the first flush fails; the bridge says so once
    and goes on, and closes without a second complaint."""
    from sim_bridge.onboard_log.logger import OnboardLog

    (tmp_path / "00000001.BIN").symlink_to("/dev/full")       # a disk that is full under the vehicle
    log = OnboardLog(tmp_path)
    with BridgeThread(SPEEDUP, params=QUIET) as b:
        b.bridge.onboard_log = log
        gcs = Gcs(b.port, SPEEDUP)
        try:
            gcs.connect()
            _arm(gcs, True)
            time.sleep(0.5)
            assert gcs.recv("ATTITUDE") is not None               # still flying
        finally:
            gcs.close()
    err = capsys.readouterr().err
    assert err.count("the on-board log stopped") == 1 and log.failed and log.file is None


@pytest.mark.process
def test_the_targets_logged_are_those_the_vehicle_holds_and_the_review_measures_them(tmp_path):
    # MANUAL holds nothing: ATT's Des* and CTUN's DAlt are NaN. ALT_HOLD holds the depth it had on entry and a level
    # attitude with the sticks centred, as ArduSub's controllers log their targets.
    with BridgeThread(SPEEDUP, start_depth=2.0, params=QUIET, log_dir=str(tmp_path)) as b:
        gcs = Gcs(b.port, SPEEDUP)
        try:
            gcs.connect()
            _arm(gcs, True)
            time.sleep(0.3)
            assert gcs.command(176, 1, 2).result == 0                            # DO_SET_MODE ALT_HOLD
            gcs.recv("HEARTBEAT", cond=lambda m: m.get_srcSystem() == 1 and m.custom_mode == 2)
            time.sleep(1.0)
            _arm(gcs, False)
        finally:
            gcs.close()
    path = tmp_path / "00000001.BIN"
    records = read_records(path, ["ATT", "CTUN", "MODE"])
    switch = records["MODE"]["TimeUS"][records["MODE"]["Mode"] == 2][0]
    ctun, att = records["CTUN"], records["ATT"]
    manual = ctun["TimeUS"] < switch
    assert manual.any() and np.isnan(ctun["DAlt"][manual]).all()
    assert np.isnan(att["DesRoll"][att["TimeUS"] < switch]).all()
    held = (ctun["TimeUS"] > switch) & np.isfinite(ctun["DAlt"])
    assert held.sum() >= 5 and np.ptp(ctun["DAlt"][held]) < 1e-6                 # one depth target, held
    assert ctun["DAlt"][held][0] == pytest.approx(ctun["Alt"][ctun["TimeUS"] <= switch][-1], abs=0.05)
    level = att["DesRoll"][(att["TimeUS"] > switch) & np.isfinite(att["DesRoll"])]
    assert level.size >= 5 and np.allclose(level, 0.0)                            # sticks centred: level
    stretches = review_dive(path).metrics["ardusub_tracking"]
    assert [s["mode"] for s in stretches] == ["ALT_HOLD"]
    errors = stretches[0]["errors"]
    assert set(errors) == {"depth_m", "roll_deg", "pitch_deg", "yaw_deg"}
    depth = ctun["DAlt"][held] - ctun["Alt"][held]
    assert errors["depth_m"]["max"] == pytest.approx(np.abs(depth).max(), rel=1e-6) and errors["depth_m"]["max"] < 0.1
