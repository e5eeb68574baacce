"""The `rov-mav` command: one subcommand per job, each defined in its own module.

A subcommand module provides `register(subparsers)`, which adds its parser and sets `func(args) -> int`.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from rov_mav.config import ConfigError

SUBCOMMAND_MODULES = (
    "rov_mav.commands.simulate",
    "rov_mav.commands.tune",
    "rov_mav.commands.run",
    "rov_mav.commands.sim_bridge",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="rov-mav",
        description="Fly a BlueROV2 Heavy (ArduSub, real or SITL, or the built-in simulator) along planned "
        "trajectories with the fuzzy-adaptive backstepping law.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in SUBCOMMAND_MODULES:
        importlib.import_module(name).register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except ConfigError as exc:
        print(f"rov-mav: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:   # an output path that cannot be written, a device that cannot be opened
        print(f"rov-mav: error: {exc.filename or ''}: {exc.strerror or exc}".replace(": : ", ": "), file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
