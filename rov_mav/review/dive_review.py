"""A dive reviewed: a run's log folder or any ArduSub telemetry log, measured against a mission when there is one.

What it is measured against:
- a run's log folder: the reference the controller flew (ticks.csv), or `mission` re-sampled at the ticks' times;
- a telemetry log: `mission` from its start (`reference.mission_start`), else the vehicle's own mission (the
  MISSION_ITEM_INT traffic in the log) as waypoints, by cross-track error; else nothing, and what needs no
  reference is still reported (loop timing, telemetry gaps, saturation, battery, modes).
Times in the review are vehicle seconds since the mission's start (or since the first arming, or the first state).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rov_mav.config import ConfigError
from rov_mav.flight.session.link import CHANNELS, mavlink
from rov_mav.flight.record.runlog import BODY, DOF, PWMS, REFERENCE, REPORTED, THRUSTS, TRUTH, per_dof, per_wrench
from rov_mav.mission.metrics import loop_figures, pwm_activity, run_metrics, truth_metrics
from rov_mav.mission.missions import Mission
from rov_mav.offline.simulation import Trace
from rov_mav.review import analysis, controller_tracking
from rov_mav.review.dataflash_log import read_dataflash_dive
from rov_mav.review.dive import Dive, DiveRecorder
from rov_mav.review.logdir import RunFolder, column_block, read_run_folder
from rov_mav.review.reference import mission_start, path_deviation, waypoint_path
from rov_mav.review.series import last_known
from rov_mav.review.tlog import ReadReport, read_tlog
from rov_mav.telemetry.entities import TickColumns

AUTO = 3                         # ArduSub's custom_mode of AUTO
MATCH_TICKS = 50                 # ticks matched against the log's states to find their vehicle time
LISTED_GAPS = 20                 # telemetry gaps put in the events one by one
TRUTH_WALL = 0.1                 # log s: a SIM_STATE recorded this near a state is its truth
SEVERITY_LEVEL = {mavlink.MAV_SEVERITY_EMERGENCY: "ERROR", mavlink.MAV_SEVERITY_ALERT: "ERROR",
                  mavlink.MAV_SEVERITY_CRITICAL: "ERROR", mavlink.MAV_SEVERITY_ERROR: "ERROR",
                  mavlink.MAV_SEVERITY_WARNING: "WARNING"}


@dataclass
class DiveReview:
    label: str                                    # what was read, for titles
    metrics: dict                                 # the metrics JSON
    warnings: list[str]
    events: list[tuple[float, str, str]]          # (t, text, level), sorted by t
    trace: Trace | None                           # the states (the reference and the controller's internals when
    internals: bool                               #   known: `internals`), for the figures
    columns: TickColumns | None                   # the same for the Rerun recording
    planned: np.ndarray | None                    # (M, 3) the vehicle's mission's waypoints
    reference_path: np.ndarray | None             # (M, 3) what the camera frames and the planned line shows
    thrusters: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)   # name -> (t, pwm (M, 8))
    limits: tuple[np.ndarray, np.ndarray] = (np.full(CHANNELS, 1100.0), np.full(CHANNELS, 1900.0))
    timeline: list[tuple[str, dict[str, tuple[np.ndarray, np.ndarray]]]] = field(default_factory=list)
    marks: list[tuple[float, str]] = field(default_factory=list)    # arming and mode changes (t, text)
    targets: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)   # ArduSub's error to its own
                                                  # targets where a mode held them: name -> (t, error)


def dive_name(path: str | Path) -> str:
    """A short name for what `path` holds: a log folder's name, a log file's name without its suffix."""
    path = Path(path)
    return path.name if path.is_dir() else path.stem


def review_dive(path: str | Path, mission: Mission | None = None, start: float | None = None) -> DiveReview:
    """Read and measure the dive at `path` (a run's log folder, or a .tlog). ConfigError (one line) when nothing
    usable could be read."""
    path = Path(path)
    if path.is_dir():
        return _review_folder(path, read_run_folder(path), mission, start)
    report, dive = read_dive(path)
    return _review_tlog(path, report, dive, mission, start)


# -- reading ---------------------------------------------------------------------------------------------------

def read_dive(path: Path) -> tuple[ReadReport, Dive]:
    """A telemetry log (.tlog) or a DataFlash log (.BIN) decoded as a `Dive` (ConfigError, one line, if nothing of a
    vehicle is in it)."""
    report = ReadReport(str(path), 0)
    if path.suffix.lower() == ".bin":
        dive = read_dataflash_dive(path, report)
    else:
        recorder = DiveRecorder()
        for wall, msg in read_tlog(path, report):
            recorder.take(wall, msg)
        dive = recorder.finish()
    if report.messages == 0:
        what = "dataflash record" if path.suffix.lower() == ".bin" else "MAVLink message"
        raise ConfigError(f"{path}: no {what} could be read ({report.size} bytes: not a telemetry log?)")
    if dive.vehicle is None:
        raise ConfigError(f"{path}: {report.messages} messages but none from a vehicle (no vehicle HEARTBEAT, "
                          "no ATTITUDE): not a telemetry log of a dive?")
    return report, dive


def _read_warnings(report: ReadReport, dive: Dive, t0: float) -> list[str]:
    """The damage and where the log stopped, in bytes and review time."""
    out = []
    if not report.complete:
        last = None if report.last_wall is None else float(analysis.vehicle_time(dive, [report.last_wall])[0]) - t0
        out.append(report.describe() + ("" if last is None else f"; last good record at t = {last:.2f} s"))
    if dive.vehicle_type is not None and dive.vehicle_type != mavlink.MAV_TYPE_SUBMARINE:
        out.append(f"the vehicle (sysid {dive.vehicle[0]}) is not a submarine (MAV_TYPE {dive.vehicle_type}): "
                   "ArduSub's mode names may not apply")
    return out


# -- a telemetry log -------------------------------------------------------------------------------------------

def _review_tlog(path: Path, report: ReadReport, dive: Dive, mission: Mission | None,
                 start: float | None) -> DiveReview:
    t0, how = mission_start(dive, start)
    t0 = t0 if t0 is not None else 0.0
    warnings = _read_warnings(report, dive, t0)
    window = analysis.armed_window(dive)
    t = dive.state_t - t0
    trace = columns = planned = reference_path = None
    metrics: dict = {}
    tested = _main_commander(dive.motor_tests, dive, window)     # a run on ArduSub's motor test
    main = tested if tested is not None else _main_commander(dive.overrides, dive, window)
    stream = dive.motor_tests if tested is not None else dive.overrides
    command_t = analysis.vehicle_time(dive, stream[main][0]) if main is not None else np.zeros(0)
    if mission is not None and t.size:
        flown = _mission_span(t, mission.duration)
        if not flown.any():
            warnings.append(f"no state in the log between the mission's start (t0 = {t0:.2f} s since boot, "
                            f"{how}) and its end: nothing to measure against it")
        reference = mission.reference(t)
        metrics.update(_tracking(mission.name, None, t[flown], dive.eta[flown], reference[flown, :6], None,
                                 completed=bool(flown.any() and t[flown][-1] >= mission.duration)))
        metrics.update(truth_metrics(_truth_at(dive, dive.state_wall[flown]), reference[flown, :6]))
        reference_path = mission.sampled_reference(0.1)[:, :3]
        metrics["reference"] = {"kind": "mission", "source": mission.source, "mission_start_s": t0,
                                "mission_start_from": how}
    else:
        reference = None
        planned, labels, note = waypoint_path(dive, path.name)
        metrics["reference"] = {"kind": "waypoints" if planned is not None else "none", "note": note,
                                "time_zero_s": t0, "time_zero_from": how}
        if planned is not None and t.size:
            metrics["path"] = _path_metrics(dive, planned, labels)
            reference_path = planned
        elif dive.mission and planned is None:
            warnings.append(note)
    if t.size:
        trace = _trace(t, dive.eta, dive.nu, reference)
        columns = _tlog_columns(dive, t, t0, reference, command_t)
    elif dive.attitude.size:
        columns = _attitude_columns(dive, t0, command_t)
        warnings.append("no position in the log (no LOCAL_POSITION_NED: no position source, as on most BlueROV2s): "
                        "attitude, depth, heading, rangefinder, thrusters and battery reviewed; the recording shows "
                        "the vehicle at north = east = 0")
    thrusters = main is not None and (tested is not None or _passthrough(dive))
    latency = analysis.loop_latency(dive.state_wall, stream[main][0]) if thrusters else np.zeros(0)
    in_window = _within(command_t, window)
    loop = loop_figures(command_t[in_window], latency)
    if main is None:
        loop["source"] = "no RC overrides"
    elif tested is not None:
        loop["source"] = (f"MAV_CMD_DO_MOTOR_TEST from sysid {main}, thruster PWMs (ArduSub's motor test); latency "
                          "on the log's clock")
    else:
        loop["source"] = f"RC_CHANNELS_OVERRIDE from sysid {main}, " + (
            "thruster PWMs (RCIN passthrough); latency on the log's clock" if thrusters
            else "pilot inputs (outputs not on passthrough)")
    outputs = _within(dive.servo_t, window)
    loop["pwm_activity_us_per_s"] = pwm_activity(dive.servo_t[outputs], dive.servo[outputs])   # as reported
    metrics["loop"] = loop
    review = DiveReview(label=path.name, metrics=metrics, warnings=warnings, events=[], trace=trace, internals=False,
                        columns=columns, planned=planned, reference_path=reference_path)
    commands = {} if not thrusters else {f"commanded (sysid {main})": (command_t[in_window] - t0,
                                                                       stream[main][1][in_window])}
    kind = "DataFlash log" if report.dataflash else "telemetry log"
    _dive_figures(review, dive, t0, window, commands, source=kind)
    metrics["ardusub_tracking"], review.targets = _ardusub_tracking(report, dive, t0)
    if dive.onboard:
        metrics["onboard"] = dive.onboard
    for unit in ("m", "mps", "deg"):
        lines = {name.removesuffix(f"_{unit}").replace("_", " "): series for name, series in review.targets.items()
                 if name.endswith(f"_{unit}")}
        if lines:
            review.timeline.append((f"ArduSub's error to its targets ({unit.replace('mps', 'm/s')})", lines))
    metrics["source"] = _source(path, kind, report)
    return review


def _ardusub_tracking(report: ReadReport, dive: Dive, t0: float) -> tuple[list[dict], dict]:
    """ArduSub's own controllers against the targets it logged, per armed stretch of a mode (`controller_tracking`),
    and each target's errors where a mode held it, as (review s, error); times in review seconds."""
    end = report.last_wall if report.last_wall is not None else \
        float(dive.heartbeat_wall[-1]) if dive.heartbeat_wall.size else 0.0
    stretches = controller_tracking.armed_stretches(dive.heartbeat_wall, dive.armed, dive.mode, end)
    out = controller_tracking.figures(stretches, dive.targets)
    for entry in out:
        entry["from_s"], entry["to_s"] = (float(v) - t0 for v in
                                          analysis.vehicle_time(dive, [entry["from_s"], entry["to_s"]]))
    series = {name: (analysis.vehicle_time(dive, errors.t) - t0, errors.error)
              for name, errors in controller_tracking.held(stretches, dive.targets).items()}
    return out, series


def _passthrough(dive: Dive) -> bool:
    """Were the thrusters on RCIN passthrough (SERVOn_FUNCTION = 50 + n) at some point, so that RC overrides are
    thruster PWMs (as a rov-mav run sends them) rather than a pilot's inputs?"""
    return any(name == "SERVO1_FUNCTION" and value == 51 for _, name, value in dive.param_changes) or \
        dive.params.get("SERVO1_FUNCTION") == 51


def _mission_span(t: np.ndarray, duration: float) -> np.ndarray:
    """Samples from the mission's start to the first at or after its end (as the runner's last tick)."""
    flown = t >= 0.0
    beyond = np.flatnonzero(t >= duration)
    if beyond.size:
        flown &= np.arange(t.size) <= beyond[0]
    return flown


def _path_metrics(dive: Dive, planned: np.ndarray, labels: list[str]) -> dict:
    """Cross-track error to the path flown through the waypoints (from where the vehicle was when the samples start,
    as ArduSub starts a mission from where it is) while in AUTO (else while armed), and each waypoint's closest
    approach."""
    if dive.mode.size:
        mode = last_known(dive.heartbeat_wall, dive.mode, dive.state_wall)
        armed = last_known(dive.heartbeat_wall, dive.armed, dive.state_wall)
    else:
        mode, armed = np.zeros(dive.state_t.size, int), np.zeros(dive.state_t.size, bool)
    auto = (mode == AUTO) & armed
    used = auto if auto.any() else armed if armed.any() else np.ones(dive.state_t.size, bool)
    position = dive.eta[used, :3]
    cross = path_deviation(position, np.vstack([position[:1], planned])) if position.size else np.zeros(0)
    closest = [float(np.min(np.linalg.norm(position - p, axis=1))) if position.size else float("nan")
               for p in planned]
    return {"waypoints": [[float(v) for v in p] for p in planned], "labels": labels,
            "samples_from": "AUTO" if auto.any() else "armed" if armed.any() else "whole log",
            "samples": int(position.shape[0]),
            "rms_cross_track_m": float(np.sqrt(np.mean(cross**2))) if cross.size else float("nan"),
            "max_cross_track_m": float(cross.max()) if cross.size else float("nan"),
            "closest_approach_m": closest}


def _tlog_columns(dive: Dive, t: np.ndarray, t0: float, reference: np.ndarray | None,
                  command_t: np.ndarray, eta: np.ndarray | None = None) -> TickColumns:
    """The states (or `eta` at times t) as ticks for Rerun; outputs, battery and link figures held at each tick."""
    eta = dive.eta if eta is None else eta
    pwm = last_known(dive.servo_t - t0, dive.servo, t) if dive.servo_t.size else None
    voltage = last_known(analysis.vehicle_time(dive, dive.power_wall) - t0, dive.voltage, t) \
        if dive.power_wall.size else None
    age = np.diff(t, prepend=t[0])
    window = np.searchsorted(command_t - t0, t, side="right") - np.searchsorted(command_t - t0, t - 1.0)
    return TickColumns(t=t, eta=eta, reference=reference, tau=None, tau_hat=None, s=None, gamma=None, pwm=pwm,
                       telemetry_age=age, control_rate=window.astype(float), battery_voltage=voltage)


def _attitude_columns(dive: Dive, t0: float, command_t: np.ndarray) -> TickColumns:
    """Without a position: ticks at the ATTITUDE samples, the vehicle at north = east = 0, its depth the Bar30's
    (held; 0 without it), for the recording."""
    t = analysis.vehicle_time(dive, dive.attitude_wall) - t0
    depth = analysis.dive_depth(dive)
    down = last_known(analysis.vehicle_time(dive, depth[0]) - t0, depth[1], t) if depth is not None \
        else np.zeros(t.size)
    eta = np.column_stack([np.zeros(t.size), np.zeros(t.size), down, dive.attitude])
    return _tlog_columns(dive, t, t0, None, command_t, eta)


def _truth_at(dive: Dive, wall: np.ndarray) -> np.ndarray:
    """(N, 3) the true position (SIM_STATE) recorded with each of these log times, NaN where none was within
    TRUTH_WALL s (a real vehicle's log has none)."""
    out = np.full((wall.size, 3), np.nan)
    if not dive.truth_wall.size:
        return out
    i = np.clip(np.searchsorted(dive.truth_wall, wall), 0, dive.truth_wall.size - 1)
    before = np.clip(i - 1, 0, dive.truth_wall.size - 1)
    nearest = np.where(np.abs(dive.truth_wall[before] - wall) < np.abs(dive.truth_wall[i] - wall), before, i)
    close = np.abs(dive.truth_wall[nearest] - wall) <= TRUTH_WALL
    out[close] = dive.truth[nearest[close]]
    return out


# -- a run's log folder ----------------------------------------------------------------------------------------

def _review_folder(path: Path, folder: RunFolder, mission: Mission | None, start: float | None) -> DiveReview:
    warnings = list(folder.warnings)
    ticks, info = folder.ticks, folder.info
    report = dive = None
    if folder.tlog is not None:
        try:
            report, dive = read_dive(folder.tlog)
        except ConfigError as exc:
            warnings.append(str(exc))
    has_ticks = "t" in ticks and ticks["t"].size > 0
    if not has_ticks and dive is None:
        raise ConfigError(f"{path}: no tick in ticks.csv and nothing readable in mavlink.tlog")
    offset, how = (None, "")
    if dive is not None:
        offset, how = _tick_offset(ticks, dive) if has_ticks else mission_start(dive, start)
        warnings += _read_warnings(report, dive, offset or 0.0)
    metrics: dict = {}
    trace = columns = None
    reference_path = mission.sampled_reference(0.1)[:, :3] if mission is not None else None
    if has_ticks:
        t = ticks["t"]
        eta = column_block(ticks, DOF)
        reference = column_block(ticks, REFERENCE)
        if mission is not None:
            flying = t >= 0
            reference[flying] = mission.reference(t[flying])
        internals = {name: column_block(ticks, per_wrench(name))
                     for name in ("tau", "tau_hat")}
        s, gamma = (column_block(ticks, per_dof(prefix))
                    for prefix in ("s", "gamma"))
        flown = (t >= 0) & _fresh(ticks)
        truth = info.get("true_disturbance")
        metrics.update(_tracking(mission.name if mission else info.get("mission", "unknown"), info.get("controller"),
                                 t[flown], eta[flown], reference[flown, :6],
                                 {name: value[flown] for name, value in internals.items()},
                                 completed=any(text == "stopping: mission complete" for _, _, text in folder.events),
                                 true_disturbance=truth))
        if flown.any():
            errors = controller_tracking.run_errors(t[flown], eta[flown], reference[flown, :6])
            label = f"rov-mav ({info.get('controller') or 'controller not logged'})"
            metrics["rov_mav_tracking"] = controller_tracking.stretch_figures(label, float(t[flown][0]),
                                                                              float(t[flown][-1]) + 1e-9, errors)
        reported = column_block(ticks, REPORTED)[flown] if REPORTED[0] in ticks else None   # older logs lack it
        metrics.update(truth_metrics(column_block(ticks, TRUTH)[flown], reference[flown, :6], eta[flown, :3],
                                     reported))
        latency = ticks["latency"] * 1e3 if "latency" in ticks else np.full(t.size, np.nan)
        metrics["loop"] = {**loop_figures(t, latency), "source": "ticks.csv",
                           "pwm_activity_us_per_s": pwm_activity(t, column_block(ticks, PWMS))}   # as the run's
        metrics["reference"] = {"kind": "mission" if mission is not None else "ticks.csv",
                                "source": mission.source if mission is not None else "ticks.csv",
                                "mission_start_s": offset, "mission_start_from": how or "unknown (no mavlink.tlog)"}
        nu = column_block(ticks, BODY)
        trace = Trace(t=t, eta=eta, nu=nu, reference=reference, tau=internals["tau"], tau_hat=internals["tau_hat"],
                      s=s, gamma=gamma, true_disturbance=None if truth is None else np.array(truth, dtype=float),
                      completed=metrics["completed"])
        if reference_path is None:
            reference_path = reference[flown, :3] if flown.any() else reference[:, :3]
        columns = TickColumns(
            t=t, eta=eta, reference=reference, tau=internals["tau"], tau_hat=internals["tau_hat"], s=s, gamma=gamma,
            thrusts=column_block(ticks, THRUSTS),
            pwm=column_block(ticks, PWMS),
            true_disturbance=None if truth is None else np.broadcast_to(np.array(truth, float), (t.size, 6)),
            progress=ticks.get("progress"), telemetry_age=ticks.get("telemetry_age"),
            control_rate=ticks.get("control_rate"), battery_voltage=ticks.get("battery_voltage"))
    review = DiveReview(label=path.name, metrics=metrics, warnings=warnings, events=[], trace=trace,
                        internals=has_ticks, columns=columns, planned=None, reference_path=reference_path)
    commands = {"commanded (ticks.csv)": (ticks["t"], column_block(ticks, PWMS))} \
        if has_ticks else {}
    review.events += _run_events(folder.events, float(ticks["t"][0]) if has_ticks else 0.0,
                                 {text for *_, text in dive.texts} if dive is not None else set())
    watchdog = _watchdog_from_events(folder.events)
    if dive is not None and offset is not None:
        window = (float(ticks["t"][0] + offset), float(ticks["t"][-1] + offset)) if has_ticks else \
            analysis.armed_window(dive)
        _dive_figures(review, dive, offset, window, commands, source="run log")
    elif has_ticks:
        review.thrusters.update(commands)
        review.metrics["battery"] = _battery_from_ticks(ticks)
        if dive is not None:
            warnings.append("could not place ticks.csv in mavlink.tlog's time (no mission-start announcement and "
                            "no tick's state found in it): figures from the telemetry log left out")
    metrics["watchdog"] = watchdog
    metrics["source"] = _source(path, "run log", report)
    review.events.sort(key=lambda e: e[0])
    return review


def _tick_offset(ticks: dict[str, np.ndarray], dive: Dive) -> tuple[float | None, str]:
    """Vehicle s since boot of the ticks' t = 0: announced in the log, else found by matching ticks' states with
    the log's (a tick's state is the log's, unless the run read a newer attitude in the same batch)."""
    t0, how = mission_start(dive)
    if how.startswith("announced"):
        return t0, how
    eta = column_block(ticks, DOF)
    offsets = []
    for k in range(min(MATCH_TICKS, eta.shape[0])):
        same = np.flatnonzero(np.all(np.isclose(dive.eta, eta[k], rtol=1e-7, atol=1e-9), axis=1))
        if same.size == 1:
            offsets.append(dive.state_t[same[0]] - ticks["t"][k])
    if not offsets:
        return None, ""
    return float(np.median(offsets)), "ticks.csv's states found in mavlink.tlog"


def _run_events(events: list[tuple[float, str, str]], first_tick: float, vehicle_texts: set[str]
                ) -> list[tuple[float, str, str]]:
    """events.csv as review events: those the run wrote before its first tick (stamped 0) at the first tick, and
    without its echoes of the vehicle's STATUSTEXT when the telemetry log has them."""
    out, looping = [], False
    for t, level, text in events:
        looping = looping or t != 0.0
        if text.startswith("vehicle: ") and text.removeprefix("vehicle: ") in vehicle_texts:
            continue
        out.append((t if looping else first_tick, text, level.upper()))
    return out


def _watchdog_from_events(events: list[tuple[float, str, str]]) -> dict:
    """Stale-telemetry episodes as the run reported them (its final count when it got that far)."""
    stale = sum(1 for _, _, text in events if text.startswith("telemetry stale"))
    for _, _, text in events:
        if text.startswith("watchdog: telemetry went stale"):
            stale = int(text.split("stale ")[1].split(" ")[0])
    return {"episodes": stale, "source": "events.csv"}


def _battery_from_ticks(ticks: dict[str, np.ndarray]) -> dict:
    v, t = ticks.get("battery_voltage", np.zeros(0)), ticks["t"]
    if not v.size:
        return {}
    i = int(np.argmin(v))
    return {"start_v": float(v[0]), "min_v": float(v[i]), "min_at_s": float(t[i]), "end_v": float(v[-1]),
            "consumed_mah": float("nan"), "consumed_from": None}


# -- shared ----------------------------------------------------------------------------------------------------

def _fresh(ticks: dict[str, np.ndarray]) -> np.ndarray:
    """The ticks on a new state: a run predicting its state also commands between samples, on the last state carried
    forward (the same vehicle_time again); its metrics count each state once, as the run's own do."""
    vehicle_time = ticks.get("vehicle_time")
    if vehicle_time is None:
        return np.ones(ticks["t"].size, dtype=bool)
    return np.concatenate([[True], np.diff(vehicle_time) != 0])


def _tracking(name: str, controller: str | None, t: np.ndarray, eta: np.ndarray, eta_d: np.ndarray,
              internals: dict[str, np.ndarray] | None, completed: bool,
              true_disturbance: list[float] | None = None) -> dict:
    """`run_metrics` (the JSON of `simulate` and `run`); the controller's figures are None when not logged."""
    tau = internals["tau"] if internals else np.full_like(eta, np.nan)
    tau_hat = internals["tau_hat"] if internals else np.zeros((0, 6))
    truth = None if true_disturbance is None else np.array(true_disturbance, dtype=float)
    metrics = run_metrics(name, controller, t, eta, eta_d, tau, tau_hat, truth, completed)
    if internals is None:
        metrics["control_effort"] = None
    return metrics


def _main_commander(streams: dict[int, tuple[np.ndarray, np.ndarray]], dive: Dive,
                    window: tuple[float, float] | None) -> int | None:
    """The station that sent the most of `streams` (RC overrides, motor tests) within `window`."""
    best, most = None, 0
    for sysid, (wall, _) in streams.items():
        n = int(_within(analysis.vehicle_time(dive, wall), window).sum())
        if n > most:
            best, most = sysid, n
    return best


def _within(t: np.ndarray, window: tuple[float, float] | None) -> np.ndarray:
    return np.ones(t.size, bool) if window is None else (t >= window[0]) & (t <= window[1])


def _trace(t: np.ndarray, eta: np.ndarray, nu: np.ndarray, reference: np.ndarray | None) -> Trace:
    unknown = np.full((t.size, 6), np.nan)
    return Trace(t=t, eta=eta, nu=nu, reference=reference if reference is not None else np.full((t.size, 18), np.nan),
                 tau=unknown, tau_hat=unknown, s=unknown, gamma=unknown, true_disturbance=None, completed=True)


def _dive_figures(review: DiveReview, dive: Dive, t0: float, window: tuple[float, float] | None,
                  commands: dict[str, tuple[np.ndarray, np.ndarray]], source: str) -> None:
    """What the telemetry log says whatever the reference: telemetry, commands, saturation, battery, modes, texts."""
    m = review.metrics
    state_t = dive.state_t[_within(dive.state_t, window)]
    link = analysis.telemetry(state_t)
    gaps = link.pop("gap_times")
    m["telemetry"] = {**link, "window_s": None if window is None else [window[0] - t0, window[1] - t0]}
    if "watchdog" not in m:
        m["watchdog"] = {"episodes": link["gaps"], "source": f"telemetry gaps > {analysis.STALE_PERIODS:g} periods "
                                                           f"({source})"}
    m["commands"] = analysis.command_rates(dive, window)
    low, high = analysis.pwm_limits(dive.params)
    review.limits = (low, high)
    servo_in = _within(dive.servo_t, window)
    m["saturation"] = {"limits_us": [[float(v) for v in low], [float(v) for v in high]],
                       "outputs": analysis.saturation(dive.servo[servo_in], low, high)}
    for name, (_, pwm) in commands.items():
        m["saturation"]["commands"] = {**analysis.saturation(pwm, low, high), "from": name}
    review.thrusters = {**commands, "outputs (SERVO_OUTPUT_RAW)": (dive.servo_t - t0, dive.servo)}
    m["battery"] = analysis.battery(dive)
    if math.isfinite(m["battery"]["min_at_s"]):
        m["battery"]["min_at_s"] -= t0
    changes = [(ti - t0, text) for ti, text in analysis.mode_changes(dive)]
    m["modes"] = [{"t": t, "event": text} for t, text in changes]
    review.marks = changes
    events = review.events
    events += [(t, text, "INFO") for t, text in changes]
    texts_t = analysis.vehicle_time(dive, [w for w, *_ in dive.texts]) - t0 if dive.texts else []
    vehicle = dive.vehicle[0]
    for ti, (_, sysid, severity, text) in zip(texts_t, dive.texts):
        who = "vehicle" if sysid == vehicle else f"sysid {sysid}"
        events.append((float(ti), f"{who}: {text}", SEVERITY_LEVEL.get(severity, "INFO")))
    m["statustext"] = {"count": len(dive.texts), "warnings": sum(1 for _, s, sev, _ in dive.texts
                                                                 if s == vehicle and sev <= 4)}
    for wall, name, value in dive.param_changes:
        events.append((float(analysis.vehicle_time(dive, [wall])[0]) - t0, f"parameter {name} = {value:g}", "INFO"))
    for wall, text in dive.mission_progress:
        events.append((float(analysis.vehicle_time(dive, [wall])[0]) - t0, text, "INFO"))
    for t_gap, dt in gaps[:LISTED_GAPS]:
        events.append((t_gap - t0, f"telemetry gap: {dt * 1e3:.0f} ms without a state", "WARNING"))
    events.sort(key=lambda e: e[0])
    review.timeline = _timeline(dive, t0, state_t, link["stale_after_ms"])
    m["vehicle"] = {"sysid": vehicle, "compid": dive.vehicle[1], "type": dive.vehicle_type,
                    "other_systems": sorted(dive.others), **analysis.identity(dive)}
    m["sensors"] = analysis.own_sensors(dive)


def _timeline(dive: Dive, t0: float, state_t: np.ndarray, stale_ms: float) -> list:
    """Panels of the timeline figure: time between states (and the watchdog's limit), battery, depth (the estimate's
    and the Bar30's), attitude, heading, the rangefinder."""
    panels = []
    if state_t.size > 1:
        ends = state_t[[1, -1]] - t0
        panels.append(("state interval (ms)", {"ATTITUDE + LOCAL_POSITION_NED": (state_t[1:] - t0,
                                                                                  1e3 * np.diff(state_t)),
                                                "stale (3 periods)": (ends, np.full(2, stale_ms))}))
    power_t = analysis.vehicle_time(dive, dive.power_wall) - t0
    if np.isfinite(dive.voltage).any():
        panels.append(("battery (V)", {"voltage": (power_t, dive.voltage)}))
    if np.isfinite(dive.current).any():
        panels.append(("current (A)", {"current": (power_t, dive.current)}))
    depth = analysis.dive_depth(dive)
    if dive.state_t.size or depth is not None:
        lines = {"z (the estimate)": (dive.state_t - t0, dive.eta[:, 2])} if dive.state_t.size else {}
        if depth is not None:
            lines["Bar30" if depth[2].startswith("Bar30") else "ArduSub"] = (
                analysis.vehicle_time(dive, depth[0]) - t0, depth[1])
        panels.append(("depth (m)", lines))
    if dive.attitude.size:
        att_t = analysis.vehicle_time(dive, dive.attitude_wall) - t0
        degrees = np.degrees(dive.attitude)
        panels.append(("attitude (deg)", {"roll": (att_t, degrees[:, 0]), "pitch": (att_t, degrees[:, 1])}))
        # turns unwrapped: a heading jittering about north is not drawn as lines from 0 to 360 deg
        panels.append(("heading (deg)", {"yaw": (att_t, np.degrees(np.unwrap(dive.attitude[:, 2])))}))
    if dive.range_m.size:
        panels.append(("above the bottom (m)", {"rangefinder": (analysis.vehicle_time(dive, dive.range_wall) - t0,
                                                                dive.range_m)}))
    return panels


def _source(path: Path, kind: str, report: ReadReport | None) -> dict:
    out: dict = {"path": str(path), "kind": kind}
    if report is not None:
        out["tlog"] = {"path": report.path, "bytes": report.size, "messages": report.messages,
                       "complete": report.complete, "read_up_to_byte": report.end,
                       "power_off_tail": report.power_off_tail,
                       "damaged_bytes": [[a, b] for a, b in report.damaged], "timestamps_replaced": report.fixed_times,
                       "unchecked_messages": [{"sysid": s, "compid": c, "msgid": m, "count": n}
                                              for (s, c, m), n in sorted(report.unchecked.items())]}
    return out
