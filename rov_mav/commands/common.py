"""Command-line options shared by the subcommands that fly a mission (simulate, run, tune): the mission file, the
controller, the Rerun sink."""

from __future__ import annotations

import argparse
import sys
import textwrap
from pathlib import Path
from typing import TYPE_CHECKING

from rov_mav.commands.arguments import (
    lat_lon,
    plan_speed,
    require_writable,
    six_floats,
    unwritable,
    vehicle_file,
)
from rov_mav.config import ConfigError
from rov_mav.control.controller import KINDS, ControllerSettings, load_settings

if TYPE_CHECKING:   # the Rerun SDK loads only when a command opens a recording (`rov-mav --help` stays fast)
    import numpy as np
    import rerun as rr

    from rov_mav import telemetry
    from rov_mav.mission.mission_items import PlanOptions
    from rov_mav.mission.missions import Mission
    from rov_mav.model.vehicle import Vehicle

MISSION_HELP = ("mission: a shipped mission's name (e.g. square; `rov-mav missions` lists them) or a file: our "
                "YAML (e.g. my_square.yaml), a QGroundControl plan (e.g. survey.plan), or a YAML naming a plan "
                "(plan: FILE.plan) with its environment and limits")
VEHICLE_HELP = "a shipped vehicle's name (`rov-mav vehicles` lists them) or a vehicle YAML file"


RUN_ONLY = ("ardusub-guided",)      # no law of ours: `run` streams the reference to the vehicle's controller
LOG_PROGRESS_INTERVAL_S = 30.0      # a progress bar written to a file or a pipe (a CI log) updates this seldom


def progress_bar(**options):
    """A tqdm bar on stderr: live on a terminal, a line every LOG_PROGRESS_INTERVAL_S into a log."""
    from tqdm import tqdm

    return tqdm(file=sys.stderr, mininterval=0.1 if sys.stderr.isatty() else LOG_PROGRESS_INTERVAL_S, **options)


def add_plan_options(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("QGroundControl plans and vehicle missions")
    group.add_argument("--origin", type=lat_lon, metavar="LAT,LON",
                       help="where local (0, 0) is: waypoints become north/east metres from here (default: the "
                            "plan's planned home, or the vehicle's home)")
    group.add_argument("--plan-speed", type=plan_speed, metavar="M/S",
                       help="speed of the legs between waypoints (default: the plan's cruise speed, or the "
                            "vehicle's WP_SPD or, before 4.7, WPNAV_SPEED); DO_CHANGE_SPEED items still change it")
    group.add_argument("--skip-unflyable", action="store_true",
                       help="leave out (and list) items this controller cannot fly (takeoff, land, return to "
                            "launch, camera, servo, jumps...) instead of refusing the plan")


def plan_options(args: argparse.Namespace) -> PlanOptions:
    from rov_mav.mission.mission_items import PlanOptions

    return PlanOptions(origin=args.origin, speed=args.plan_speed, skip_unflyable=args.skip_unflyable)


def load_mission(args: argparse.Namespace) -> Mission:
    """The mission named on the command line (YAML or .plan), with the plan options; items left out are listed on
    stderr."""
    from rov_mav.mission.loader import load

    mission = load(args.mission, plan_options(args))
    report_skipped(mission)
    return mission


_NAVIGATION_ERRORS: dict[tuple, object] = {}


def navigation_errors(navigation, seed: int, reference, dt: float):
    """The offline loops' `NavigationErrors`: the built-in vehicle's estimate along the mission
    (`sim_bridge.navigation.estimate_errors`) as a run's law meets it (`flight.state.estimate_shaping`), computed once
    per (navigation, seed,
    reference, dt) in this process (a bench flies each held-out run with every controller)."""
    from rov_mav.flight.state.estimate_shaping import as_the_run_sees
    from sim_bridge.navigation.estimate_errors import estimate_errors

    key = (navigation, seed, reference.shape, hash(reference.tobytes()), dt)
    if key not in _NAVIGATION_ERRORS:
        _NAVIGATION_ERRORS[key] = as_the_run_sees(estimate_errors(navigation, seed, reference, dt), reference, dt)
    return _NAVIGATION_ERRORS[key]


def report_skipped(mission: Mission) -> None:
    for line in mission.skipped:
        print(f"rov-mav: {mission.source}: {line}", file=sys.stderr)


def add_controller_options(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("controller")
    group.add_argument("--controller", choices=[*KINDS, *RUN_ONLY], default="fuzzy",
                       help="the report's backstepping law with fuzzy adaptation rates (Appendix III), constant "
                            "rates, or none (baseline); or pid (ArduSub-style cascade), smc (sliding mode per DOF), "
                            "ismc (integral sliding mode with the model's feed-forward); `run` only: ardusub-guided "
                            "(no law of ours: ArduSub's GUIDED mode flies the reference); default: fuzzy")
    group.add_argument("--gains", metavar="FILE",
                       help="YAML with any of the controller's keys (e.g. the output of `rov-mav tune`): k1, k2, "
                            "constant_gamma, d_max for the report's law (default: our PSO's, tuned on the link `run` "
                            "flies; the word `report`: the report's own Eqs. 4.1-4.2); pid, smc, ismc: see their "
                            "files in rov_mav/data")
    group.add_argument("--k1", type=six_floats, metavar="A,B,C,D,E,F", help="k1 diagonal, overrides --gains")
    group.add_argument("--k2", type=six_floats, metavar="A,B,C,D,E,F", help="k2 diagonal, overrides --gains")
    group.add_argument("--fuzzy-rules", metavar="FILE", help="fuzzy rule base YAML (default: Appendix III)")
    group.add_argument("--vehicle", type=vehicle_file, metavar="NAME|FILE",
                       help=f"the controller's vehicle model: {VEHICLE_HELP} (default: bluerov2_heavy)")


def add_signing_options(parser: argparse.ArgumentParser, effect: str) -> None:
    """--signing-key FILE | --signing-passphrase TEXT; `effect` says what a key does for this command."""
    group = parser.add_argument_group("MAVLink 2 signing", textwrap.fill(effect, 96))
    key = group.add_mutually_exclusive_group()
    key.add_argument("--signing-key", metavar="FILE", help="the key: a file of exactly 32 raw bytes")
    key.add_argument("--signing-passphrase", metavar="TEXT",
                     help="the key: SHA-256 of this ASCII passphrase, as MAVProxy's `signing setup TEXT` and "
                          "`signing key TEXT` derive it")


def signing_key(args: argparse.Namespace) -> bytes | None:
    """The key the signing options give (ConfigError, one line, if the file or passphrase is unusable), or None."""
    from rov_mav.signing import key_from_file, key_from_passphrase

    if args.signing_key is not None:
        return key_from_file(args.signing_key)
    if args.signing_passphrase is not None:
        return key_from_passphrase(args.signing_passphrase)
    return None


def controller_settings(args: argparse.Namespace) -> ControllerSettings:
    """The law's settings; ConfigError (one line) for a controller that only `run` can fly."""
    if args.controller in RUN_ONLY:
        raise ConfigError(f"--controller {args.controller}: ArduSub's GUIDED mode flies it, so only `rov-mav run` "
                          "can use it (here: one of " + ", ".join(KINDS) + ")")
    return load_settings(args.controller, args.gains, args.fuzzy_rules, args.k1, args.k2)


def _rerun_target(text: str) -> telemetry.RerunTarget:
    from rov_mav import telemetry

    try:
        target = telemetry.parse_target(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    problem = unwritable(target.location, folder=False) if target.mode == "save" else None
    if problem is not None:
        raise argparse.ArgumentTypeError(f"{target.location}: {problem}")
    return target


def check_rerun_output(args: argparse.Namespace, default_file: str | Path) -> None:
    """ConfigError now, before any work, if the recording would go to `default_file` and that cannot be written
    (the default without a display, or the fallback when no viewer answers)."""
    if args.rerun is None or args.rerun.mode in ("spawn", "connect"):
        require_writable(default_file, folder=False, option="--rerun (default save)")


def add_rerun_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--rerun", type=_rerun_target, metavar="spawn|connect[:URL]|save:FILE.rrd|off",
                        help="live telemetry in the Rerun viewer: spawn a viewer (the default with a display), "
                             "connect to a running one (default: Rerun's local viewer port, e.g. "
                             "`rerun --serve-grpc`), save a recording (the default without a display), or off")


def rerun_recording(args: argparse.Namespace, default_file: str | Path, reference_path: np.ndarray | None = None,
                    tuning: bool = False, ardusub_targets: bool = False
                    ) -> tuple[telemetry.RerunTarget, rr.RecordingStream | None]:
    """The --rerun target (default: spawn with a display, else save to `default_file`) and its open recording,
    whose default layout frames `reference_path` (M, 3) (with the PSO tab when `tuning`, ArduSub's errors to its
    targets when `ardusub_targets`). Without a viewer to stream to, it saves instead."""
    from rov_mav import telemetry

    target = args.rerun or telemetry.default_target(default_file)
    if target.mode == "off":
        return target, None
    blueprint = telemetry.default_blueprint(reference_path, tuning, ardusub_targets)
    try:
        return target, telemetry.open_recording(target, blueprint)
    except telemetry.ViewerUnavailable as exc:
        print(f"rov-mav: {exc}; saving the telemetry to {default_file} instead", file=sys.stderr)
        target = telemetry.RerunTarget("save", str(default_file))
        return target, telemetry.open_recording(target, blueprint)


def rerun_sink(args: argparse.Namespace, vehicle: Vehicle, mission: Mission, default_file: str | Path
               ) -> tuple[telemetry.RerunTarget, telemetry.RerunSink | None]:
    """The --rerun target and a runner sink streaming to it (None when off); print `target.describe()` after."""
    from rov_mav import telemetry

    path = mission.sampled_reference(0.1)[:, :3]
    target, rec = rerun_recording(args, default_file, path)
    return target, None if rec is None else telemetry.RerunSink(rec, vehicle, path)
