"""`rov-mav autotune`: tune the law for this vehicle in the water, in one command: plan, excite, identify, tune,
check, keep. Each step is the command a user would run by hand (`run`, `identify`, `tune`), on the files the last
one wrote, inside a box around where the vehicle is (`mission.autotune_plan`)."""

from __future__ import annotations

import argparse
import json
import shutil
import signal
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import yaml

from rov_mav.commands.arguments import (
    cluster_address,
    count,
    mavlink_target,
    mission_file,
    number,
    require_writable,
    vehicle_file,
)
from rov_mav.config import ConfigError
from rov_mav.offline.autotune_report import write_report

DESCRIPTION = """\
Tune the controller for the vehicle on the link, in the water, in six steps, each said as it starts:
  1 plan      the vehicle checked by a dry run (a hold where it is); then where it is now, the box around it (--box,
              at --depth), what will be flown, for how long, within which limits, and which files will be written
              (--dry-run stops here)
  2 excite    the shipped identify mission (206 s; --excitation), moved to start where the vehicle is, flown with
              the current gains
  3 identify  the vehicle fitted from that flight's log, the shipped model (or --vehicle) as prior, while a run
              holds the vehicle where the check starts; a fit that predicts worse than the prior on held-back data,
              or that no vehicle can be, stops here
  4 tune      PSO of the gains on the fitted vehicle, on the check square, robust to the fit's uncertainty (the
              plant scaled by the widest relative 95 % interval of its fitted mass and damping, 5-30 %), within
              --budget seconds (one thread), the vehicle still holding station
  5 check     the check square (about 64 s) flown twice, old gains then new
  6 keep      the new gains kept only when their position error is at least --margin smaller; the vehicle file,
              the gains, the logs and report.md in --out
Every flight is a `rov-mav run`: any limit crossed or a pilot taking over ends it with the run's safe stop, and the
command says which step it reached. Each run stops when the vehicle strays 0.5 m from its reference, and every
reference lies inside the box, so the vehicle never leaves the box by more than 0.5 m."""

EPILOG = """\
examples:
  rov-mav autotune --target udpin:0.0.0.0:14550 --dry-run
  rov-mav autotune --target udpin:0.0.0.0:14550 --out out/autotune
  rov-mav run --target udpin:0.0.0.0:14550 square --vehicle out/autotune/vehicle.yaml --gains out/autotune/gains.yaml

exit status: 0 the new gains kept; 4 the procedure completed but the new gains were not better by --margin (the old
kept); otherwise the status of the step that stopped it (a run's, identify's, tune's; 2 bad arguments)."""

STEPS = ("plan", "excite", "identify", "tune", "check", "keep")
NOT_BETTER = 4                   # the procedure completed, the new gains were not better (a run's 3 is a handover)
HOLD_SLACK = 300.0               # s the station hold lasts beyond the tune's budget: the fit's time (its end is the tune's)
POLL = 0.2                       # wall s between looks at the tune and the hold
UNCERTAINTY = (0.05, 0.3)        # the plant scale's spread for the tune: at least 5 %, at most 30 %


def configure(p: argparse.ArgumentParser) -> None:
    p.description, p.epilog, p.formatter_class = DESCRIPTION, EPILOG, argparse.RawDescriptionHelpFormatter
    p.add_argument("--target", required=True, type=mavlink_target, metavar="CONN",
                   help="pymavlink connection to the vehicle, as `rov-mav run --target` takes it")
    p.add_argument("--controller", choices=("baseline", "constant", "fuzzy", "pid", "smc", "ismc"), default="fuzzy",
                   help="the law to tune (default fuzzy)")
    p.add_argument("--gains", metavar="FILE", help="the current gains (default: the shipped ones)")
    p.add_argument("--vehicle", type=vehicle_file, metavar="NAME|FILE", default=vehicle_file("bluerov2_heavy"),
                   help="the model flown before the fit and the fit's prior (default bluerov2_heavy)")
    p.add_argument("--box", type=_box, default=np.array([3.0, 3.0, 1.5]), metavar="X,Y,Z",
                   help="the box's size north, east and down, m (default 3,3,1.5)")
    p.add_argument("--excitation", type=mission_file, default=mission_file("identify"), metavar="NAME|FILE",
                   help="the identification flight, moved to start where the vehicle is (default: the shipped "
                        "identify, 206 s in a 2.5 x 2.3 x 1.4 m box; a mission of your own for a smaller pool)")
    p.add_argument("--depth", type=number(0.0, 300.0), metavar="D",
                   help="depth at which the excitation starts, m (default: the vehicle's)")
    p.add_argument("--budget", type=number(1.0, 3600.0), default=90.0, metavar="S",
                   help="wall seconds for the tune (default 90)")
    p.add_argument("--particles", type=count(10_000), default=30, help="the swarm's size (default 30)")
    p.add_argument("--cluster", type=cluster_address, metavar="ADDR", help="tune on Dask (as `rov-mav tune`)")
    p.add_argument("--margin", type=number(0.0, 0.9), default=0.1, metavar="F",
                   help="how much smaller the new gains' RMS position error must be to keep them (default 0.1)")
    p.add_argument("--out", default="out/autotune", metavar="DIR", help="folder to write (default out/autotune)")
    p.add_argument("--dry-run", action="store_true", help="plan and check the vehicle, fly nothing")
    p.set_defaults(func=main)


def _box(text: str) -> np.ndarray:
    try:
        size = np.array([float(v) for v in text.split(",")])
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text}: not X,Y,Z") from None
    if size.shape != (3,) or not np.all(np.isfinite(size) & (size > 0) & (size <= 100)):
        raise argparse.ArgumentTypeError(f"{text}: need three sizes in m, each above 0 and at most 100")
    return size


def main(args: argparse.Namespace) -> int:
    signal.signal(signal.SIGTERM, _interrupted)      # as Ctrl-C: the step's flight stops safely, its children too
    out = require_writable(args.out, folder=True, option="--out")
    out.mkdir(parents=True, exist_ok=True)
    _step(1, "plan")
    excitation = _excitation(args)
    if code := _vehicle_check(args, out, excitation[0]):
        return _stopped(1, code)
    excite, check = _plan(args, out, *excitation)   # where the vehicle is now: it may have drifted in the check
    if args.dry_run:
        return 0
    _step(2, "excite: the identification excitation, with the current gains")
    if code := _fly(args, excite, out / "excite", args.gains, args.vehicle):
        return _stopped(2, code)
    _step(3, "identify: the vehicle from the excitation's log, while it holds station where the check starts")
    with _holding_station(args, out, check) as holding:
        code, fitted = _identify(args, out)
        if code := code or _held(holding):
            return _stopped(3, code)
        _step(4, f"tune: {args.controller} on the fitted vehicle, {args.budget:g} s, while it holds station")
        if code := _tune(args, out, check, _uncertainty(fitted), holding):
            return _stopped(4, code)
    _step(5, "check: the check square, old gains then new")
    runs = {}
    for label, gains in (("old", args.gains), ("new", str(out / "tuned-gains.yaml"))):
        if code := _fly(args, check, out / f"check-{label}", gains, str(out / "vehicle.yaml")):
            return _stopped(5, code)
        runs[label] = json.loads((out / f"check-{label}" / "metrics.json").read_text())
    _step(6, "keep")
    return _keep(args, out, runs, fitted)


def _interrupted(signum, frame) -> None:
    raise KeyboardInterrupt


def _step(n: int, text: str) -> None:
    gap = "\n" if n > 1 else ""           # a blank line between the steps
    print(f"{gap}autotune: step {n} of {len(STEPS)}, {text}", flush=True)


def _stopped(step: int, code: int) -> int:
    print(f"rov-mav autotune: stopped at step {step} of {len(STEPS)} ({STEPS[step - 1]}), exit status {code}; the "
          "vehicle is as that step's run left it", file=sys.stderr)
    return code


def _excitation(args: argparse.Namespace):
    """The excitation: (its file's contents, the mission); ConfigError when it is not a mission YAML."""
    from rov_mav.mission.missions import load_mission

    if Path(args.excitation).suffix.lower() not in (".yaml", ".yml"):
        raise ConfigError(f"{args.excitation}: --excitation takes a mission YAML (its legs are moved to the vehicle)")
    return yaml.safe_load(Path(args.excitation).read_text()), load_mission(args.excitation)


def _pose(args: argparse.Namespace) -> np.ndarray:
    from rov_mav.flight.session.link import LinkError
    from rov_mav.flight.session.vehicle_position import vehicle_pose

    try:
        return vehicle_pose(args.target)
    except LinkError as exc:
        raise ConfigError(str(exc)) from None


def _vehicle_check(args: argparse.Namespace, out: Path, spec: dict) -> int:
    """A dry run of a hold where the vehicle is: the link, the vehicle, its frame and outputs checked, nothing moved."""
    from rov_mav import cli
    from rov_mav.mission.autotune_plan import hold_here

    hold = out / "vehicle-check.yaml"
    hold.write_text(yaml.safe_dump(hold_here(_pose(args), args.box, spec.get("limits", {})), sort_keys=False,
                                   default_flow_style=None))
    print("  the vehicle checked by a dry run (a hold where it is):", flush=True)
    return cli.main([*_run_args(args, hold, args.gains, args.vehicle), "--dry-run"])


def _plan(args: argparse.Namespace, out: Path, spec: dict, excitation) -> tuple[Path, Path]:
    """The box around where the vehicle is now, the missions written into --out (the excitation, the check square),
    plan.json, what will be flown."""
    from rov_mav.mission.autotune_plan import MAX_EXCURSION, check_leg, moved_excitation
    from rov_mav.mission.missions import mission_from_dict

    pose = _pose(args)
    start = np.array([pose[0], pose[1], pose[2] if args.depth is None else args.depth])
    moved, box = moved_excitation(spec, excitation, start, args.box)
    square = check_leg(box)
    paths = out / "excite.yaml", out / "check.yaml"
    for path, content in zip(paths, (moved, square)):
        path.write_text(yaml.safe_dump(content, sort_keys=False, default_flow_style=None))
    check_duration = mission_from_dict(square, str(paths[1])).duration
    (out / "plan.json").write_text(json.dumps({
        "vehicle": {"north": pose[0], "east": pose[1], "depth": pose[2], "heading_rad": pose[3]},
        "box": {"low": box.low.tolist(), "high": box.high.tolist()}, "max_excursion_m": MAX_EXCURSION,
        "excitation": str(args.excitation), "excitation_s": excitation.duration, "check_s": check_duration,
        "tune_budget_s": args.budget}, indent=2) + "\n")
    print(f"  the vehicle is at north {pose[0]:.2f}, east {pose[1]:.2f} m, {pose[2]:.2f} m deep, heading "
          f"{np.degrees(pose[3]):.0f} deg\n  box: {box.describe()}\n"
          f"  excite: {excitation.name} moved to start at north {start[0]:.2f}, east {start[1]:.2f}, depth "
          f"{start[2]:.2f} m: {excitation.duration:.0f} s ({paths[0]})\n"
          f"  tune: at most {args.budget:g} s, the vehicle holding station meanwhile where the check starts\n"
          f"  check: a {square['description'][2:]} at {square['start']['position'][2]:.2f} m, twice: "
          f"{check_duration:.0f} s each ({paths[1]})\n"
          f"  limits: each run stops {MAX_EXCURSION:g} m from its reference or {moved['limits']['max_depth']:g} m "
          f"deep, at {moved['limits']['max_thrust']:g} N per thruster\n"
          f"  writes into {out}: plan.json, vehicle.yaml, gains.yaml, the runs' logs (excite, check-old, "
          "check-new), report.md",
          flush=True)
    return paths


def _run_args(args: argparse.Namespace, mission: Path, gains: str | None, vehicle: str) -> list[str]:
    command = ["run", "--target", args.target, str(mission), "--controller", args.controller, "--vehicle", vehicle,
               "--rerun", "off"]
    return command + (["--gains", gains] if gains else [])


def _fly(args: argparse.Namespace, mission: Path, log: Path, gains: str | None, vehicle: str) -> int:
    from rov_mav import cli

    return cli.main([*_run_args(args, mission, gains, vehicle), "--log", str(log), "--metrics",
                     str(log / "metrics.json")])


def _identify(args: argparse.Namespace, out: Path):
    from rov_mav.cli import build_parser
    from rov_mav.commands.identify import fitted_vehicle

    argv = ["identify", str(out / "excite"), "--vehicle", args.vehicle, "--out", str(out / "vehicle.yaml")]
    return fitted_vehicle(build_parser("identify").parse_args(argv))


def _uncertainty(fitted) -> float:
    """The widest relative 95 % interval of the fitted added mass and damping, within UNCERTAINTY."""
    spreads = [e.half_width / abs(e.value) for e in fitted.estimates
               if e.status == "fitted" and e.name.startswith(("added_mass", "damping")) and e.value != 0.0]
    return float(np.clip(max(spreads, default=UNCERTAINTY[1]), *UNCERTAINTY))


@contextmanager
def _holding_station(args: argparse.Namespace, out: Path, check: Path):
    """A `rov-mav run` holding the vehicle where the check starts (its own process, the model it was excited with),
    from the end of the excitation until the tune is done: yields the process; its safe stop (SIGINT) on leaving."""
    from rov_mav.mission.autotune_plan import station_hold

    hold = out / "station.yaml"
    hold.write_text(yaml.safe_dump(station_hold(yaml.safe_load(check.read_text()), args.budget + HOLD_SLACK),
                                   sort_keys=False, default_flow_style=None))
    holding = _child(_run_args(args, hold, args.gains, args.vehicle) + ["--log", str(out / "station")])
    try:
        yield holding
    finally:
        _end(holding)


def _held(holding: subprocess.Popen) -> int:
    """0 while the station hold runs, else its exit status (1 if it exited 0: it should not have ended)."""
    if holding.poll() is None:
        return 0
    print(f"  the station hold ended (exit {holding.returncode}): the vehicle is no longer held", flush=True)
    return holding.returncode or 1


def _tune(args: argparse.Namespace, out: Path, check: Path, spread: float, holding: subprocess.Popen) -> int:
    """Step 4: `rov-mav tune` in a process of its own (one thread) while the vehicle holds station; a hold that ends
    first stops it."""
    scenarios = out / "scenarios.yaml"
    scenarios.write_text(yaml.safe_dump({
        "description": f"the fitted vehicle and plants {spread:.0%} lighter and heavier (its fit's uncertainty)",
        "scenarios": [{"name": "fitted"}, {"name": "lighter", "plant_scale": round(1.0 - spread, 4)},
                      {"name": "heavier", "plant_scale": round(1.0 + spread, 4)}]}, sort_keys=False))
    argv = ["tune", str(check), "--vehicle", str(out / "vehicle.yaml"), "--controller", args.controller,
            "--scenarios", str(scenarios), "--particles", str(args.particles), "--iterations", "100000",
            "--budget", f"{args.budget:g}", "--out", str(out / "tuned-gains.yaml"), "--plot", str(out / "tune"),
            "--rerun", "off", "--threads", "1", *(["--gains", args.gains] if args.gains else []),
            *(["--cluster", args.cluster] if args.cluster else [])]
    tuning = _child(argv)
    try:
        while tuning.poll() is None:
            if code := _held(holding):
                return code
            time.sleep(POLL)
        return tuning.returncode
    finally:
        _end(tuning)


def _end(child: subprocess.Popen) -> None:
    """A child stopped as Ctrl-C stops it (a run: its safe stop), and waited for."""
    if child.poll() is None:
        child.send_signal(signal.SIGINT)
    child.wait()


def _child(argv: list[str]) -> subprocess.Popen:
    """`rov-mav ARGV` as a process of its own, its output on ours."""
    return subprocess.Popen([sys.executable, "-m", "rov_mav.cli", *argv])


def _keep(args: argparse.Namespace, out: Path, runs: dict, fitted) -> int:
    """Step 6: the new gains kept only when better by --margin (against the truth where the link carries it)."""
    key = _error_key(runs)
    old, new = runs["old"][key], runs["new"][key]
    better = new <= (1.0 - args.margin) * old
    if better:
        shutil.copyfile(out / "tuned-gains.yaml", out / "gains.yaml")
    verdict = (f"the new gains kept in gains.yaml: {key} {new * 100:.2f} cm against {old * 100:.2f} cm" if better else
               f"the new gains were not better by {args.margin:.0%} ({key} {new * 100:.2f} cm against "
               f"{old * 100:.2f} cm): keep flying the old ones (the tuned ones are in tuned-gains.yaml)")
    report = write_report(out, runs, key, fitted.fits, verdict, _check_errors(out))
    print(f"  {verdict}\n  report: {report}", flush=True)
    if not better:
        print(f"rov-mav autotune: {verdict}", file=sys.stderr)
    return 0 if better else NOT_BETTER


def _error_key(runs: dict) -> str:
    """The position error the check is judged on: against the truth when both runs had it, else the estimate."""
    truth = "rms_position_error_truth_m"
    return truth if all(truth in r for r in runs.values()) else "rms_position_error_m"


def _check_errors(out: Path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Each check flight's position error over its mission time (against the truth where its log has it)."""
    from rov_mav.flight.record.runlog import DOF, REFERENCE, TRUTH
    from rov_mav.review.logdir import column_block, read_run_folder

    errors = {}
    for label in ("old", "new"):
        ticks = read_run_folder(out / f"check-{label}").ticks
        flown = ticks["t"] >= 0.0
        truth = column_block(ticks, TRUTH)
        position = truth if np.all(np.isfinite(truth[flown])) else column_block(ticks, DOF)[:, :3]
        error = np.linalg.norm(position - column_block(ticks, REFERENCE)[:, :3], axis=1)
        errors[label] = (ticks["t"][flown], error[flown])
    return errors
