"""A run's ticks.csv read back gives the run's own metrics exactly: its times are written as the run held them, so a
sample on the steady-state window's boundary falls on the same side in the run and in `analyze`."""

from __future__ import annotations

import numpy as np
import pytest

from rov_mav.flight.record.runlog import RunLog
from rov_mav.flight.record.tick import TickRecord
from rov_mav.mission.metrics import run_metrics
from rov_mav.review.logdir import read_run_folder

POSE = ["x", "y", "z", "phi", "theta", "psi"]


def test_tick_times_round_trip_exactly_and_the_metrics_agree(tmp_path):
    start = 296.5800000000000409                                   # a mission start off the 20 ms grid
    vehicle = start + 0.0413371764 + 0.02 * np.arange(753)         # stamps as a 50 Hz stream gives them
    t = vehicle - start
    rng = np.random.default_rng(7)
    eta = rng.normal(0.0, 0.01, (t.size, 6))
    eta_d = np.zeros((t.size, 6))
    log = RunLog(tmp_path)
    for k in range(t.size):
        log.log_tick(TickRecord(t=t[k], vehicle_time=vehicle[k], eta=eta[k], nu=np.zeros(6),
                                reference=np.concatenate([eta_d[k], np.zeros(12)]), tau=np.zeros(6),
                                tau_hat=np.zeros(6), s=np.zeros(6), gamma=np.zeros(6), thrusts=np.zeros(8),
                                pwm=np.full(8, 1500.0), progress=0.0, telemetry_age=0.0, latency=0.0,
                                control_rate=50.0, battery_voltage=16.0))
    log.close()
    ticks = read_run_folder(tmp_path).ticks
    assert np.array_equal(ticks["t"], t) and np.array_equal(ticks["vehicle_time"], vehicle)
    read_eta = np.stack([ticks[c] for c in POSE], axis=1)
    read_eta_d = np.stack([ticks[c + "_d"] for c in POSE], axis=1)
    ours = run_metrics("m", "c", t, eta, eta_d, eta, eta, None, True)
    theirs = run_metrics("m", "c", ticks["t"], read_eta, read_eta_d, read_eta, read_eta, None, True)
    for key in ("duration_s", "rms_position_error_m", "rms_position_error_steady_m", "rms_attitude_error_steady_rad"):
        assert theirs[key] == pytest.approx(ours[key], rel=1e-7), key


@pytest.mark.parametrize("damage, stop_row, why", [
    (b"1.5,2", 40, "cut short"),                             # a row cut short by a kill, no end of line
    (b"\n", 40, "fields, expected"),                         # a blank line (numpy's reader would skip it)
    (b"nope", 40, "'nope' is not a number"),                 # (in place of the row's first value)
])
def test_a_whole_file_and_one_read_row_by_row_agree_up_to_where_it_stopped(tmp_path, damage, stop_row, why):
    """A well-formed ticks.csv is parsed at once, a damaged one row by row; the rows before the damage are the same
    numbers either way, and the damage's line is named."""
    log = RunLog(tmp_path)
    rng = np.random.default_rng(3)
    for k in range(60):
        log.log_tick(TickRecord(t=0.02 * k, vehicle_time=100 + 0.02 * k, eta=rng.normal(size=6), nu=rng.normal(size=6),
                                reference=rng.normal(size=18), tau=rng.normal(size=6), tau_hat=np.zeros(6),
                                s=np.zeros(6), gamma=np.zeros(6), thrusts=np.zeros(8), pwm=np.full(8, 1500.0),
                                progress=0.0, telemetry_age=0.0, latency=0.0, control_rate=50.0,
                                battery_voltage=16.0))
    log.close()
    whole = read_run_folder(tmp_path).ticks
    path = tmp_path / "ticks.csv"
    lines = path.read_bytes().splitlines(keepends=True)
    row = lines[stop_row + 1]
    damaged = {b"nope": damage + row[row.index(b","):], b"1.5,2": damage}.get(damage, damage + row)
    path.write_bytes(b"".join(lines[:stop_row + 1]) + damaged + (b"".join(lines[stop_row + 2:])
                                                                 if damage != b"1.5,2" else b""))
    cut = read_run_folder(tmp_path)
    assert any(f"line {stop_row + 2} " in w and why in w for w in cut.warnings), cut.warnings
    for name, column in whole.items():
        assert np.array_equal(cut.ticks[name], column[:stop_row], equal_nan=True), name
