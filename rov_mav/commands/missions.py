"""`rov-mav missions`: the shipped missions and scenario sets, by the names the other commands take."""

from __future__ import annotations

import argparse
import os

from rov_mav import shipped

WHERE = {   # kind: the commands that take it by name
    "mission": "run, simulate, tune, bench --missions, analyze/identify --mission, sim-bridge --environment",
    "scenario set": "tune --scenarios, bench --training/--scenarios",
    "vehicle": "--vehicle, simulate --plant-params",
}


def configure(p: argparse.ArgumentParser) -> None:
    p.description = ("List the missions and scenario sets that ship with rov-mav: give a name where a file is "
                     "asked for (e.g. `rov-mav simulate square`); an existing file of that name is used instead.")
    p.set_defaults(func=main)


def show(*kinds: str) -> None:
    """A section per kind: a heading naming the commands that take it, then name and description per line."""
    paths = []
    for i, kind in enumerate(kinds):
        items = shipped.listing(kind)
        width = max(len(item.name) for item in items)
        print(("\n" if i else "") + f"{kind}s ({WHERE[kind]}):")
        for item in items:
            print(f"  {item.name:<{width}}  {item.description}")
        paths += [str(item.path) for item in items]
    print(f"\nthe files (copy one to change it): {os.path.commonpath(paths)}")


def main(args: argparse.Namespace) -> int:
    show("mission", "scenario set")
    return 0
