"""Command-line options shared by the subcommands that fly a mission (simulate, run, tune)."""

from __future__ import annotations

import argparse

from rov_mav.controller import SCHEDULES, ControllerSettings, load_settings


def six_floats(text: str) -> list[float]:
    """Parse 'a,b,c,d,e,f' into six floats (argparse type)."""
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not six comma-separated numbers") from None
    if len(values) != 6:
        raise argparse.ArgumentTypeError(f"'{text}' has {len(values)} values, expected 6")
    return values


def add_controller_options(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("controller")
    group.add_argument("--controller", choices=list(SCHEDULES), default="fuzzy",
                       help="disturbance adaptation: fuzzy rates (Appendix III), constant rates, or none "
                            "(baseline backstepping); default: fuzzy")
    group.add_argument("--gains", metavar="FILE",
                       help="YAML with any of k1, k2, constant_gamma, d_max (e.g. the output of `rov-mav tune`); "
                            "default: Eqs. 4.1-4.2")
    group.add_argument("--k1", type=six_floats, metavar="A,B,C,D,E,F", help="k1 diagonal, overrides --gains")
    group.add_argument("--k2", type=six_floats, metavar="A,B,C,D,E,F", help="k2 diagonal, overrides --gains")
    group.add_argument("--fuzzy-rules", metavar="FILE", help="fuzzy rule base YAML (default: Appendix III)")
    group.add_argument("--vehicle", metavar="FILE",
                       help="the controller's vehicle model YAML (default: the shipped BlueROV2 Heavy)")


def controller_settings(args: argparse.Namespace) -> ControllerSettings:
    return load_settings(args.controller, args.gains, args.fuzzy_rules, args.k1, args.k2)
