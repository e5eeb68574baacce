"""`rov-mav vehicles`: the shipped vehicle files, by the names --vehicle takes."""

from __future__ import annotations

import argparse

from rov_mav.commands.missions import show


def configure(p: argparse.ArgumentParser) -> None:
    p.description = ("List the vehicle files that ship with rov-mav: give a name to --vehicle (e.g. `--vehicle "
                     "ardusub_sitl`); an existing file of that name is used instead.")
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    show("vehicle")
    return 0
