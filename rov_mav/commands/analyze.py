"""`rov-mav analyze`: review a dive afterwards, from a run's log folder or any ArduSub telemetry log."""

from __future__ import annotations

import argparse
import json
import math
import sys

from rov_mav.commands.arguments import (
    mission_file,
    number,
    output_file,
    output_folder,
    require_writable,
    vehicle_file,
)
from rov_mav.commands.common import (
    MISSION_HELP,
    VEHICLE_HELP,
    add_plan_options,
    add_rerun_option,
    check_rerun_output,
    load_mission,
    rerun_recording,
)
from rov_mav.review import controller_tracking, onboard

DESCRIPTION = """\
Review a dive: PATH is a run's --log folder (ticks.csv, events.csv, and mavlink.tlog or the vehicle's own .BIN
copied in its place) or any ArduSub telemetry log
(.tlog: flown by rov-mav, by a pilot, or by ArduSub's own AUTO/GUIDED; written by rov-mav, MAVProxy or
QGroundControl), or the vehicle's own DataFlash log (.BIN, ArduSub 4.0 to 4.7, or `sim-bridge --log-dir`'s), read
as records by the labels of its own FMT records (ATT and RATE, XKF1 or NKF1, RCOU, BAT, BARO, CTUN, RFND, MODE and
ARM, MSG, PARM). The vehicle's state pairs attitude and position as `run` decodes them live.

Measured against: the reference the run flew (a log folder's ticks.csv), or --mission from its start (announced
on the link by rov-mav runs; else --mission-start, else the first arming), or the vehicle's own mission found in
the log (MISSION_ITEM_INT traffic) as waypoints, by cross-track error; with none, what needs no reference is still
reported. Writes what `simulate` writes (metrics JSON, PNG figures, a Rerun recording with the same layout) and
prints a one-screen summary: tracking, loop timing, telemetry gaps and watchdog events, thruster saturation
(outputs at their PWM limits), battery, modes and arming, and ArduSub's own controllers against the targets they
logged, per armed stretch of a mode (a .BIN's CTUN, PSCN/PSCE and ATT; a .tlog's NAV_CONTROLLER_OUTPUT): depth,
height above the bottom, horizontal position, roll, pitch and heading, as a run's own figures are given.

A truncated or damaged log is read as far as it goes: the summary says where (byte offset, last good time).
"""

EPILOG = """\
examples:
  rov-mav run square --log out/square/log && rov-mav analyze out/square/log
  rov-mav analyze flight.tlog                                         # a pilot's dive, or ArduSub AUTO
  rov-mav analyze flight.tlog --mission square --mission-start 812.4  # measured against the shipped square
  rov-mav analyze 00000042.BIN --mission square                       # the vehicle's own log of a run

exit status: 0 reviewed (a damaged or truncated log too, with a warning); 2 nothing usable could be read, or bad
arguments.
"""
MODES_SHOWN = 8          # mode/arming changes printed before "... and N more"


def configure(p: argparse.ArgumentParser) -> None:
    p.description, p.epilog, p.formatter_class = DESCRIPTION, EPILOG, argparse.RawDescriptionHelpFormatter
    p.add_argument("path", metavar="PATH", help="a run's --log folder, a telemetry log (.tlog), or the vehicle's own "
                                                "DataFlash log (.BIN)")
    p.add_argument("--mission", type=mission_file, metavar="NAME|FILE",
                   help=f"measure the dive against this {MISSION_HELP}")
    p.add_argument("--mission-start", type=number(0.0), metavar="S",
                   help="vehicle seconds since boot at which the mission started (default: as the rov-mav run "
                        "announced it, else the first arming)")
    add_plan_options(p)
    p.add_argument("--vehicle", type=vehicle_file, metavar="NAME|FILE",
                   help=f"the vehicle drawn in the recording: {VEHICLE_HELP} (default: bluerov2_heavy)")
    p.add_argument("--out", type=output_folder, metavar="DIR",
                   help="folder for the figures and recording (default: out/analyze-NAME)")
    p.add_argument("--metrics", type=output_file, metavar="FILE",
                   help="write the metrics JSON here (default: DIR/metrics.json)")
    add_rerun_option(p)
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    from rov_mav import telemetry
    from rov_mav.model.vehicle import load_vehicle
    from rov_mav.review.dive_review import dive_name, review_dive
    from rov_mav.review.outputs import record, write_figures

    mission = load_mission(args) if args.mission else None
    vehicle = load_vehicle(args.vehicle)
    out_dir = require_writable(args.out or f"out/analyze-{dive_name(args.path)}", folder=True, option="--out")
    metrics_path = require_writable(args.metrics or out_dir / "metrics.json", folder=False, option="--metrics")
    check_rerun_output(args, out_dir / "dive.rrd")
    review = review_dive(args.path, mission, args.mission_start)
    figures = write_figures(review, out_dir)
    metrics_path.parent.mkdir(parents=True, exist_ok=True)
    metrics_path.write_text(json.dumps(_plain(review.metrics), indent=2) + "\n")
    rerun_target, rec = rerun_recording(args, out_dir / "dive.rrd", review.reference_path,
                                        ardusub_targets=bool(review.targets))
    delivered = True
    if rec is not None:
        record(review, rec, vehicle)
        delivered = telemetry.finish(rec)
    for line in review.warnings:
        print(f"rov-mav analyze: warning: {line}", file=sys.stderr)
    for line in summary(review.label, review.metrics):
        print(line)
    print(f"  metrics: {metrics_path}")
    print(f"  figures: {', '.join(str(f) for f in figures) or 'none (no state in the log)'}")
    print(f"  rerun: {rerun_target.describe(delivered)}")
    return 0


def summary(label: str, m: dict) -> list[str]:
    """The one-screen summary of a review's metrics: what was flown and how well, the loop and the link, the
    vehicle's side."""
    return [f"{label}: {_what(m)}", *_tracking_lines(m), *_loop_lines(m), *_vehicle_lines(m)]


def _tracking_lines(m: dict) -> list[str]:
    """The mission and the tracking (or the path flown, or no reference)."""
    lines = []
    ref = m.get("reference", {})
    if "rms_position_error_m" in m:
        status = "completed" if m["completed"] else "NOT completed"
        start = ref.get("mission_start_s")
        when = f", started at {start:.2f} s since boot ({ref.get('mission_start_from')})" if start is not None else ""
        lines.append(f"  mission {m['mission']} ({ref.get('source')}){when}: {status}, {m['duration_s']:.1f} s "
                     "measured")
        lines.append(f"  tracking: position RMS {_cm(m['rms_position_error_m'])} (steady "
                     f"{_cm(m['rms_position_error_steady_m'])}, max {_cm(m['max_position_error_m'])}); attitude RMS "
                     f"{_num(m['rms_attitude_error_rad'], '.4f')} rad")
        if "rms_position_error_truth_m" in m:
            lines.append(f"  against the truth (SIM_STATE, {m['truth_samples']} samples): position RMS "
                         f"{_cm(m['rms_position_error_truth_m'])}, max {_cm(m['max_position_error_truth_m'])}")
    elif "path" in m:
        p = m["path"]
        closest = ", ".join(_cm(v) for v in p["closest_approach_m"][:6])
        lines.append(f"  {ref.get('note')}: cross-track RMS {_cm(p['rms_cross_track_m'])}, max "
                     f"{_cm(p['max_cross_track_m'])} ({p['samples_from']}); closest approach per waypoint {closest}")
    else:
        lines.append(f"  tracking: no reference ({ref.get('note', 'no mission')}; --mission FILE to measure one)")
    return lines


def _loop_lines(m: dict) -> list[str]:
    """The loop, the thrusters' activity, the telemetry, the watchdog, who commanded, the outputs' limits."""
    lines = []
    loop = m.get("loop", {})
    if loop.get("ticks"):
        latency = f"; telemetry-in to command-out p50 {loop['latency_p50_ms']:.2f} ms, p99 " \
            f"{loop['latency_p99_ms']:.2f} ms" if _finite(loop["latency_p50_ms"]) else ""
        lines.append(f"  loop: {loop['ticks']} commands at {loop['control_rate_hz']:.1f} Hz of vehicle time{latency} "
                     f"({loop['source']})")
    if _finite(loop.get("pwm_activity_us_per_s", float("nan"))):
        lines.append(f"  thrusters moved {loop['pwm_activity_us_per_s']:.0f} us/s each (mean sum |dPWM| per second, "
                     + ("as commanded)" if loop.get("source") == "ticks.csv" else "SERVO_OUTPUT_RAW as reported)"))
    if "telemetry" in m and not m["telemetry"]["samples"]:
        lines.append("  telemetry: no position state (no LOCAL_POSITION_NED in the log)")
    elif "telemetry" in m:
        tm = m["telemetry"]
        lines.append(f"  telemetry: {tm['samples']} states at {_num(tm['rate_hz'], '.1f')} Hz; {tm['gaps']} gap(s) "
                     f"longer than {_num(tm['stale_after_ms'], '.0f')} ms (longest {_num(tm['max_gap_ms'], '.0f')} ms)")
    if "watchdog" in m:
        lines.append(f"  watchdog: {m['watchdog']['episodes']} stale-telemetry episode(s) ({m['watchdog']['source']})")
    for station in m.get("commands", []):
        lines.append(f"  commands: {station['message']} from sysid {station['sysid']}: {station['count']} at "
                     f"{_num(station['rate_hz'], '.1f')} Hz")
    if "saturation" in m:
        lines.append("  thrusters at their PWM limits: " + "; ".join(
            f"{name} {_percent(s['fraction_any_at_limit'])} of samples (worst "
            f"T{1 + max(range(8), key=lambda i: s['fraction_at_limit'][i])} "
            f"{_percent(max(s['fraction_at_limit']))})"
            for name, s in m["saturation"].items() if isinstance(s, dict) and s.get("samples")) or "  no outputs")
    return lines


def _vehicle_lines(m: dict) -> list[str]:
    """What the vehicle's sensors, battery, firmware and modes said, both controllers' tracking, its own log."""
    lines = _sensor_lines(m.get("sensors", {}))
    if m.get("battery"):
        b = m["battery"]
        used = f", {b['consumed_mah']:.0f} mAh used ({b['consumed_from']})" if _finite(b.get("consumed_mah")) else ""
        lines.append(f"  battery: {_num(b['start_v'], '.2f')} V -> {_num(b['end_v'], '.2f')} V, lowest "
                     f"{_num(b['min_v'], '.2f')} V at t = {_num(b['min_at_s'], '.1f')} s{used}")
    if (v := m.get("vehicle", {})).get("firmware") or v.get("frame"):
        lines.append(f"  vehicle: ArduSub {v.get('firmware') or '(version not in the log)'}, "
                     f"{v.get('frame') or 'frame not in the log'}")
    modes = m.get("modes", [])
    if modes:
        shown = "; ".join(f"{e['t']:.1f} s {'log starts ' if i == 0 else ''}{e['event']}"
                          for i, e in enumerate(modes[:MODES_SHOWN]))
        more = f"; ... and {len(modes) - MODES_SHOWN} more" if len(modes) > MODES_SHOWN else ""
        reference = m.get("reference", {})
        zero = reference.get("time_zero_from") or reference.get("mission_start_from")
        lines.append(f"  modes{f' (t = 0: {zero})' if zero else ''}: {shown}{more}")
    if m.get("rov_mav_tracking"):
        lines.append("  rov-mav's control, " + controller_tracking.describe(m["rov_mav_tracking"]))
    for entry in m.get("ardusub_tracking", []):
        lines.append("  ArduSub's own control, " + controller_tracking.describe(entry))
    lines += onboard.describe(m.get("onboard", {}))
    if m.get("statustext", {}).get("count"):
        lines.append(f"  vehicle texts: {m['statustext']['count']} STATUSTEXT ({m['statustext']['warnings']} "
                     "warnings or worse)")
    return lines


def _sensor_lines(sensors: dict) -> list[str]:
    """What the vehicle's own sensors said (`analysis.own_sensors`), position or not."""
    lines = []
    if a := sensors.get("attitude"):
        lines.append(f"  attitude: {a['samples']} samples, roll RMS {a['roll_rms_deg']:.1f} deg, pitch RMS "
                     f"{a['pitch_rms_deg']:.1f} deg, tilt at most {a['max_tilt_deg']:.1f} deg; heading "
                     f"{a['heading_start_deg']:.0f} -> {a['heading_end_deg']:.0f} deg")
    if d := sensors.get("depth"):
        lines.append(f"  depth: {d['min_m']:.2f} to {d['max_m']:.2f} m (mean {d['mean_m']:.2f} m, {d['samples']} "
                     f"samples; {d['source']})")
    if r := sensors.get("rangefinder"):
        lines.append(f"  above the bottom (rangefinder): {r['min_m']:.2f} to {r['max_m']:.2f} m (mean "
                     f"{r['mean_m']:.2f} m, {r['samples']} samples)")
    return lines


def _what(m: dict) -> str:
    source = m.get("source", {})
    tlog = source.get("tlog")
    read = "" if tlog is None else (f"; {tlog['messages']} messages" + (
        ", DAMAGED or TRUNCATED (see the warning)" if not tlog["complete"] else
        f", ending with {tlog['bytes'] - tlog['read_up_to_byte']} bytes of an unfinished record (a power-off)"
        if tlog.get("power_off_tail") else ""))
    return f"{source.get('kind')}{read}"


def _finite(v) -> bool:
    return isinstance(v, (int, float)) and math.isfinite(v)


def _num(v, fmt: str) -> str:
    return format(v, fmt) if _finite(v) else "n/a"


def _cm(v) -> str:
    return f"{v * 100:.2f} cm" if _finite(v) else "n/a"


def _percent(v) -> str:
    return f"{100 * v:.1f} %"


def _plain(value):
    """JSON-ready: NaN and infinities become null (JSON has no NaN)."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value
