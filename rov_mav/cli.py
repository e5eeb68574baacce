"""The `rov-mav` command: one subcommand per job, each defined in its own module.

A subcommand module provides `configure(parser)`, which adds its arguments and sets `func(args) -> int`. Only the
module of the subcommand asked for is imported (each pulls in what its job needs: Numba kernels, SciPy, Rerun...);
the others appear in `rov-mav --help` by their one-line summary, so every process starts in the time its job needs.
Whatever the input, the command ends with at most one error line on stderr and no traceback: bad arguments and
files exit with status 2 (argparse's convention), Ctrl-C outside a run with 130.
"""

from __future__ import annotations

import argparse
import gc
import importlib
import sys
from typing import NoReturn

from rov_mav.config import ConfigError

SUBCOMMANDS = {   # name: (module, summary)
    "simulate": ("rov_mav.commands.simulate", "run a mission offline against the 6-DOF model (no MAVLink)"),
    "tune": ("rov_mav.commands.tune",
             "tune a controller's gains by particle swarm optimization on a mission (Sec. II.v)"),
    "bench": ("rov_mav.commands.bench",
              "compare controllers: each tuned alike on training scenarios, judged on held-out ones"),
    "run": ("rov_mav.commands.run",
            "fly a mission over MAVLink (ArduSub, SITL, or the built-in simulated vehicle)"),
    "sim-bridge": ("rov_mav.commands.sim_bridge", "run a simulated ArduSub BlueROV2 Heavy over MAVLink"),
    "analyze": ("rov_mav.commands.analyze", "review a dive from a run's log folder or any ArduSub .tlog"),
    "identify": ("rov_mav.commands.identify", "fit the vehicle model to run logs and write a vehicle file"),
    "autotune": ("rov_mav.commands.autotune",
                 "tune the law for the vehicle on the link: excite, identify, tune, check, keep"),
    "missions": ("rov_mav.commands.missions", "list the shipped missions and scenario sets (a name works as a file)"),
    "vehicles": ("rov_mav.commands.vehicles", "list the shipped vehicle files (--vehicle NAME)"),
}


class OneLineParser(argparse.ArgumentParser):
    """argparse whose errors are one line (the usage is one `--help` away); subcommands inherit it."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {one_line(message)}\n")


def one_line(text: str) -> str:
    """`text` with any line break shown as \\n (a file name may hold one)."""
    return text.replace("\r", "\\r").replace("\n", "\\n")


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The parser, with `command`'s arguments (every subcommand's with None, as `--help` pages need)."""
    parser = OneLineParser(
        prog="rov-mav",
        description="Fly a BlueROV2 Heavy (ArduSub, real or SITL, or the built-in simulator) along planned "
        "trajectories with the fuzzy-adaptive backstepping law.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, (module, summary) in SUBCOMMANDS.items():
        p = sub.add_parser(name, help=summary)
        if command in (None, name):
            importlib.import_module(module).configure(p)
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    command = argv[0] if argv and argv[0] in SUBCOMMANDS else ""
    args = build_parser(command).parse_args(argv)
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


def entry() -> NoReturn:
    """The `rov-mav` console script: `main`, then the interpreter's normal exit without its last garbage collection
    (`gc.freeze`): on a loaded machine that collection of the compiled kernels' objects took seconds, after the
    vehicle was already left safe and every file closed."""
    status = main()
    gc.freeze()
    sys.exit(status)


if __name__ == "__main__":
    entry()
