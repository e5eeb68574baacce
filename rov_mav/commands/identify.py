"""`rov-mav identify`: fit the vehicle model to run logs and write it as a vehicle file."""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

from rov_mav.commands.arguments import mission_file, number, output_file, vehicle_file
from rov_mav.commands.common import MISSION_HELP, VEHICLE_HELP, add_plan_options, load_mission

DESCRIPTION = """\
Fit the vehicle model the controller uses to one or more run logs (`rov-mav run --log DIR`), ideally of
the shipped mission identify flown on the vehicle to identify, and write it as a vehicle file that --vehicle accepts.

Fitted, as far as the logs can tell them apart: added mass, linear and quadratic damping (per DOF), buoyancy and
its lever r_b - r_g, the thrusters' force per PWM (a scale on the vehicle file's curve, forward and reverse, and the
horizontal thrusters' scale against the vertical ones), their moment arms (roll, pitch, yaw) and the horizontal
thrusters' height (their roll and pitch arm), plus the delay from command to thrust. Mass, inertia and the
centre of gravity come from the prior (--vehicle), which also stands wherever the data cannot see: each parameter
is printed with its 95 % confidence interval, or with the reason it kept the prior, and each DOF with how much of
its force the model explains (R^2) and the residual left (RMS).

One number cannot come from motion: scaling every force of the model and the thrust together changes nothing the
vehicle does. The thrusters' bench data set that level unless --net-buoyancy gives the vehicle's weight in water
(weigh it hanging from a spring scale, fully submerged): then the thrust scale is fitted too.

Before anything is written, the model is checked: fitted again on two of every three 10 s blocks of each log, it
predicts the third block one second ahead (depth, heading, roll, pitch: integrated from each logged state with the
thrust the vehicle was sent) beside the prior. A fit that predicts depth or heading worse than the prior, or a
vehicle no ROV can be (a mass matrix not positive definite, negative damping, buoyancy more than 25 % from the
weight), is not written: one line says why. A DataFlash log's frame (FRAME_CONFIG, or ArduSub's "Frame:" text)
must be the prior's (the shipped bluerov2 is the standard six-thruster BlueROV2's, bluerov2_heavy the Heavy's).

A pilot's dive (a .BIN without --mission) has no reference: its armed states are the data, the dive's own motion
smoothed over 1 s stands in for the reference, and only the DOFs it moved are fitted (each said, with how much it
moved); surge and sway only when the log holds a DVL's velocity (VISP/VISV), since the EKF's horizontal velocity
without one is drift. A dive that moved nothing enough gives no model.
"""

EPILOG = """\
examples:
  rov-mav run --target tcp:127.0.0.1:5760 identify --log out/identify
  rov-mav identify out/identify --out my_rov.yaml
  rov-mav identify out/identify out/identify2 --net-buoyancy 2.5 --out my_rov.yaml
  rov-mav run --target tcp:127.0.0.1:5760 square --vehicle my_rov.yaml
  rov-mav identify 00000016.BIN --vehicle bluerov2 --out my_bluerov2.yaml     (a pilot's dive)

exit status: 0 written; 1 a model was fitted but not written (it predicts worse than the prior, or is impossible);
2 bad arguments, unreadable logs, or logs that cannot give a model (nothing is written).
"""

MAX_NET_BUOYANCY = 1000.0   # N: |buoyancy - weight| of anything a BlueROV2's thrusters could hold down or up


def configure(p: argparse.ArgumentParser) -> None:
    p.description, p.epilog, p.formatter_class = DESCRIPTION, EPILOG, argparse.RawDescriptionHelpFormatter
    p.add_argument("logs", nargs="+", metavar="LOG",
                   help="run log directories (`rov-mav run --log DIR`), or the vehicle's own DataFlash logs (.BIN): "
                        "of runs (with --mission), or of a pilot's dives (without)")
    p.add_argument("--mission", type=mission_file, metavar="NAME|FILE",
                   help=f"for a .BIN: the {MISSION_HELP}; its start is the one the run announced (logged by the "
                        "vehicle as a GCS: message), else --mission-start")
    p.add_argument("--mission-start", type=number(0.0), metavar="S",
                   help="for a .BIN: vehicle seconds since boot at which the mission started")
    add_plan_options(p)
    p.add_argument("--out", required=True, type=output_file, metavar="FILE", help="vehicle file to write")
    p.add_argument("--vehicle", type=vehicle_file, metavar="NAME|FILE",
                   help=f"the prior: mass, inertia, geometry, and every value the logs cannot fit; {VEHICLE_HELP} "
                        "(default: bluerov2_heavy)")
    p.add_argument("--net-buoyancy", type=number(-MAX_NET_BUOYANCY, MAX_NET_BUOYANCY), metavar="N",
                   help="buoyancy minus weight in N, measured (positive: it floats); fixes the level of all forces "
                        "so that the thrust scale can be fitted")
    p.add_argument("--window", type=number(0.05, 5.0), default=None, metavar="S",
                   help="length of the integration windows in s (default 0.4)")
    p.set_defaults(func=main)


def load_dataflash_run(path: str, mission, start: float | None, prior):
    """A run as the vehicle's own DataFlash log holds it (`review.dataflash_log`: its EKF state, attitude and rates,
    RCOU's PWMs and BAT's voltage at 10 Hz): an identification `Run` and, for a pilot's dive (`mission` None), which
    DOFs it excited (`dive_runs.excitation`), else None. With a mission, the run tracks it over its span from its
    start; without, the armed states are the run and the dive's own smoothed motion its reference. Each tick's PWM
    is the motors' outputs (`dive_runs.motor_outputs`) at the middle of its interval, its thrust's sign the PWM's
    times MOT_k_DIRECTION, the state's age 0. ConfigError (one line) when the log cannot give one."""
    from rov_mav.config import ConfigError
    from rov_mav.offline.identify import dive_runs
    from rov_mav.offline.identify.identification import Run
    from rov_mav.review.analysis import vehicle_time
    from rov_mav.review.dive_review import read_dive
    from rov_mav.review.reference import mission_start
    from rov_mav.review.series import last_known

    _, dive = read_dive(Path(path))
    _same_frame(path, dive, prior)
    if dive.servo_t.size == 0 or dive.state_t.size == 0:
        raise ConfigError(f"{path}: no state or no RCOU in the log")
    try:
        outputs = dive_runs.motor_outputs(dive.params, prior.frame)
        servo = dive_runs.motor_pwm(dive.servo, outputs)
    except ConfigError as exc:
        raise ConfigError(f"{path}: {exc}") from None
    if mission is not None:
        t0, _ = mission_start(dive, start)
        if t0 is None:
            raise ConfigError(f"{path}: no mission start in the log (give --mission-start)")
        kept = (dive.state_t >= t0) & (dive.state_t <= t0 + mission.duration)
        what = f"between the mission's start ({t0:.2f} s) and its end"
    else:
        kept = last_known(vehicle_time(dive, dive.heartbeat_wall), dive.armed, dive.state_t) if dive.armed.size \
            else np.zeros(dive.state_t.size, dtype=bool)
        what = "armed"
    t = dive.state_t[kept]
    if t.size < 10:
        raise ConfigError(f"{path}: fewer than 10 states {what}")
    # the run's tick holds its PWM until the next one; the log samples the outputs at 10 Hz, so the PWM over a tick's
    # interval is the logged one at its middle (interpolated): the sample at its start would lag it by half a period
    middle = np.concatenate([0.5 * (t[1:] + t[:-1]), [t[-1]]])
    pwm = np.column_stack([np.interp(middle, dive.servo_t, servo[:, i]) for i in range(servo.shape[1])])
    boot_wall = np.interp(t, dive.clock_t, dive.clock_wall)
    voltage = np.interp(boot_wall, dive.power_wall, dive.voltage) if dive.power_wall.size else np.full(t.size, 16.0)
    sign = np.sign(pwm - 1500.0) * dive_runs.motor_directions(dive.params, servo.shape[1])
    if mission is not None:
        return Run(path, t, dive.eta[kept], dive.nu[kept], pwm, sign, voltage, mission.reference(t - t0),
                   np.zeros(t.size)), None
    reference = dive_runs.own_reference(t, dive.eta[kept])
    excited = dive_runs.excitation(reference, "external_navigation" in dive.onboard)
    return Run(path, t, dive.eta[kept], dive.nu[kept], pwm, sign, voltage, reference, np.zeros(t.size)), excited


def _same_frame(path: str, dive, prior) -> None:
    """ConfigError (one line) when the log's vehicle is on another frame than the prior (its motors would be read as
    the wrong thrusters): FRAME_CONFIG, else the banner's "Frame:" text (`analysis.logged_frames`); the remedy names
    the shipped vehicle files of the logged frame."""
    from rov_mav.config import ConfigError
    from rov_mav.model.vehicle import load_vehicle
    from rov_mav.review.analysis import logged_frames
    from rov_mav.shipped import listing

    frames, _ = logged_frames(dive)
    if frames and prior.frame not in frames:
        shipped = [s.name for s in listing("vehicle") if load_vehicle(s.path).frame in frames]
        remedy = f"give --vehicle {' or '.join(shipped)}" if shipped else "give --vehicle a model of this frame"
        raise ConfigError(f"{path}: the logged vehicle is {frames[0].describe()}; the prior {prior.name} is "
                          f"{prior.frame.describe()}: its motors would be read as other thrusters ({remedy})")


def load_run(directory: str):
    """A run's log folder as an identification `Run`: ConfigError (one line) if it is not the log of a flight."""
    from rov_mav.config import ConfigError
    from rov_mav.flight.record.runlog import BODY, DOF, PWMS, REFERENCE, THRUSTS
    from rov_mav.offline.identify.identification import Run
    from rov_mav.review.logdir import TICKS, column_block, read_run_folder

    path = Path(directory)
    if not path.is_dir():
        raise ConfigError(f"{path}: not a directory (a run log is the DIR of `rov-mav run --log DIR`)")
    folder = read_run_folder(path)
    for warning in folder.warnings:
        print(f"rov-mav identify: warning: {warning}", file=sys.stderr)
    if folder.info.get("dry_run") or any(text.startswith("dry run:") for _, _, text in folder.events):
        raise ConfigError(f"{path}: the log of a dry run: no command reached the thrusters")
    needed = ("t", *DOF, *BODY, *REFERENCE, *PWMS, *THRUSTS, "battery_voltage", "telemetry_age")
    ticks = folder.ticks
    missing = [c for c in needed if c not in ticks]
    if missing:
        raise ConfigError(f"{path / TICKS}: no column {missing[0]} (not a run log, or none at all)")
    if ticks["t"].size < 2:
        raise ConfigError(f"{path / TICKS}: {ticks['t'].size} tick(s): the run flew nothing to fit")
    for c in needed:
        if not np.all(np.isfinite(ticks[c])):
            raise ConfigError(f"{path / TICKS}: column {c} holds a value that is not a finite number")
    if np.any(np.diff(ticks["t"]) < 0):
        line = int(np.argmax(np.diff(ticks["t"]) < 0)) + 3
        raise ConfigError(f"{path / TICKS}: line {line}: time goes back")
    return Run(directory, ticks["t"], column_block(ticks, DOF), column_block(ticks, BODY), column_block(ticks, PWMS),
               column_block(ticks, THRUSTS), ticks["battery_voltage"], column_block(ticks, REFERENCE),
               ticks["telemetry_age"])


def _report(result, logs: list[str], out: str | None, window: float) -> str:
    """The table of parameters, the fit per DOF, what was kept, where the file went (None: nothing written)."""
    n = len(logs)
    lines = [f"identify: {n} log{'s' if n > 1 else ''}, {result.duration:.1f} s of flight in {result.windows} windows "
             f"of {window:g} s, command-to-thrust delay {result.delay * 1e3:.1f} ms",
             f"  {'parameter':<26} {'value':>12} {'95 % CI':>11} {'prior':>10}  {'unit':<14} status"]
    for e in result.estimates:
        ci = f"+/-{e.half_width:.3g}" if np.isfinite(e.half_width) else ""
        lines.append(f"  {e.name:<26} {e.value:>12.5g} {ci:>11} {e.prior:>10.5g}  {e.unit:<14} {e.status}")
    vehicle = result.vehicle
    lines.append(f"  net buoyancy {vehicle.buoyancy - vehicle.weight:+.2f} N (B - W); centre of buoyancy "
                 f"{np.round(vehicle.center_of_buoyancy * 1e3, 1).tolist()} mm")
    lines.append("fit per DOF (R^2: the share of its force the model explains; residual: the RMS left, per window):")
    lines += [f"  {f.dof:<6} R^2 {f.r2:.4f}  residual RMS {f.rms:.3g} {f.unit}" if np.isfinite(f.r2) else
              f"  {f.dof:<6} not fitted" for f in result.fits]
    kept = [e.name for e in result.estimates if e.status.startswith("prior")]
    lines.append(f"kept at the prior (not identifiable from these logs): {', '.join(kept) or 'nothing'}")
    if out is not None:
        lines.append(f"wrote {out} (fly with it: rov-mav run --vehicle {out} MISSION)")
    return "\n".join(lines)


def _checked(runs, prior, net_buoyancy, window, dofs):
    """The held-back check (`prediction_check`): a fit on two of every three blocks of each run, its predictions on
    the third beside the prior's; IdentificationError (one line) when the fitted blocks alone cannot be fitted."""
    from rov_mav.offline.identify.identification import MIN_DURATION, IdentificationError, identify
    from rov_mav.offline.identify.prediction_check import HELD_BACK, compare, split

    parts = [split(run) for run in runs]
    try:
        first = identify([fit for fit, _ in parts], prior, net_buoyancy, window, dofs=dofs)
    except IdentificationError as exc:
        need = MIN_DURATION / (1.0 - HELD_BACK)
        raise IdentificationError(f"the check on held-back data cannot fit two thirds of the logs ({exc}): "
                                  f"give at least {need:.0f} s of flight") from None
    return compare(first.vehicle, prior, [held for _, held in parts], first.delay)


def _refusal(result, comparisons) -> str | None:
    """Why the fitted vehicle must not be written, in one line, or None."""
    from rov_mav.offline.identify.prediction_check import DECIDING, impossible

    if why := impossible(result.vehicle):
        return f"the fitted vehicle is impossible: {why}; nothing written"
    worse = [c for c in comparisons if c.quantity in DECIDING and c.worse]
    if worse:
        return ("the fit predicts worse than the prior on the held-back blocks of the logs (1 s ahead: "
                + ", ".join(f"{c.quantity} RMS {c.fitted:.3g} against {c.prior:.3g}" for c in worse)
                + "): it would fly worse than the vehicle file you have; nothing written")
    return None


def _check_lines(comparisons) -> list[str]:
    from rov_mav.offline.identify.prediction_check import BLOCK

    lines = [f"held-back check (fitted on two of every three {BLOCK:g} s blocks of each log; RMS error 1 s ahead on "
             "the third):"]
    lines += [f"  {c.quantity:<12} fitted {c.fitted:8.3g}  prior {c.prior:8.3g}  ({c.predictions} predictions)"
              for c in comparisons]
    return lines


def _dofs(excitations) -> np.ndarray | None:
    """The DOFs to fit: all when any log is of a mission (None), else those some pilot's dive excited;
    IdentificationError (one line, each DOF's reason) when none was."""
    from rov_mav.offline.identify.identification import IdentificationError

    if any(e is None for e in excitations):
        return None
    fitted = np.any([[d.fitted for d in e] for e in excitations], axis=0)
    if not fitted.any():
        raise IdentificationError("no degree of freedom was excited enough to fit, so no model can come from these "
                                  "logs: " + "; ".join(f"{d.dof} {d.why}" for d in excitations[0]))
    return fitted


def _excitation_lines(excitations) -> list[str]:
    dives = [e for e in excitations if e is not None]
    if not dives:
        return []
    lines = ["what the dive excited (a pilot's dive: only these DOFs' balances are fitted; the rest keep the prior):"]
    for i, d in enumerate(dives[0]):
        best = max((e[i] for e in dives), key=lambda x: (x.fitted, x.motion))
        lines.append(f"  {d.dof:<6} {'fitted' if best.fitted else 'kept'}: {best.why}")
    return lines


def _load(args, prior):
    """(runs, excitations): each LOG as an identification run, with what it excited (None for a mission's)."""
    from rov_mav.config import ConfigError
    from rov_mav.model.vehicle import FLOWN_THRUSTERS

    mission = load_mission(args) if args.mission else None
    loaded = []
    for d in args.logs:
        if d.lower().endswith(".bin"):
            loaded.append(load_dataflash_run(d, mission, args.mission_start, prior))
            continue
        if len(prior.thruster_positions) != FLOWN_THRUSTERS:
            raise ConfigError(f"{d}: a run log drives {FLOWN_THRUSTERS} thrusters; the prior {prior.name} has "
                              f"{len(prior.thruster_positions)}")
        loaded.append((load_run(d), None))
    return [run for run, _ in loaded], [excited for _, excited in loaded]


def main(args: argparse.Namespace) -> int:
    return fitted_vehicle(args)[0]


def fitted_vehicle(args: argparse.Namespace):
    """The command's work: (exit status, the identification result when a vehicle file was written, else None)."""
    from rov_mav.config import ConfigError
    from rov_mav.model.vehicle import load_vehicle, save_vehicle
    from rov_mav.offline.identify.identification import WINDOW, IdentificationError, identify

    prior = load_vehicle(args.vehicle)
    window = args.window or WINDOW
    try:
        runs, excitations = _load(args, prior)
        if lines := _excitation_lines(excitations):
            print("\n".join(lines), flush=True)
        dofs = _dofs(excitations)
        result = identify(runs, prior, args.net_buoyancy, window, dofs=dofs)
        comparisons = _checked(runs, prior, args.net_buoyancy, window, dofs)
    except (ConfigError, IdentificationError) as exc:
        print(f"rov-mav identify: error: {exc}", file=sys.stderr)
        return 2, None
    if refusal := _refusal(result, comparisons):
        print(_report(result, args.logs, None, window), flush=True)
        print("\n".join(_check_lines(comparisons)), flush=True)
        print(f"rov-mav identify: refused: {refusal}", file=sys.stderr)
        return 1, None
    fitted = sum(e.status == "fitted" for e in result.estimates)
    header = (f"{prior.name}, identified by rov-mav identify from {', '.join(args.logs)}: {fitted} parameters "
              f"fitted, the rest from {args.vehicle or 'the shipped model'}\n"
              + "; ".join(f"{f.dof} R^2 {f.r2:.4f}" for f in result.fits if np.isfinite(f.r2)))
    save_vehicle(replace(result.vehicle, name=f"{prior.name}, identified"), args.out, header)
    print(_report(result, args.logs, args.out, window), flush=True)
    print("\n".join(_check_lines(comparisons)), flush=True)
    return 0, result
