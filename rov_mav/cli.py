"""The `rov-mav` command: one subcommand per job, each defined in its own module.

A subcommand module provides `register(subparsers)`, which adds its parser and sets `func(args) -> int`.
Whatever the input, the command ends with at most one error line on stderr and no traceback: bad arguments and
files exit with status 2 (argparse's convention), Ctrl-C outside a run with 130.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from typing import NoReturn

from rov_mav.config import ConfigError

SUBCOMMAND_MODULES = (
    "rov_mav.commands.simulate",
    "rov_mav.commands.tune",
    "rov_mav.commands.bench",
    "rov_mav.commands.run",
    "rov_mav.commands.sim_bridge",
    "rov_mav.commands.analyze",
    "rov_mav.commands.identify",
)


class OneLineParser(argparse.ArgumentParser):
    """argparse whose errors are one line (the usage is one `--help` away); subcommands inherit it."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {one_line(message)}\n")


def one_line(text: str) -> str:
    """`text` with any line break shown as \\n (a file name may hold one)."""
    return text.replace("\r", "\\r").replace("\n", "\\n")


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(
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
    prog = f"rov-mav {args.command}"
    try:
        return int(args.func(args) or 0)
    except ConfigError as exc:
        return _fail(prog, f"error: {exc}", 2)
    except OSError as exc:   # an output path that cannot be written, a device that cannot be opened
        return _fail(prog, f"error: {exc.filename or ''}: {exc.strerror or exc}".replace(": : ", ": "), 2)
    except KeyboardInterrupt:
        return _fail(prog, "interrupted", 130)
    except Exception as exc:   # noqa: BLE001 -- the last net: a bug, reported in one line all the same
        return _fail(prog, f"internal error (a bug, please report it): {type(exc).__name__}: {exc}", 1)


def _fail(prog: str, message: str, status: int) -> int:
    print(f"{prog}: {one_line(message)}", file=sys.stderr)
    return status


if __name__ == "__main__":
    sys.exit(main())
