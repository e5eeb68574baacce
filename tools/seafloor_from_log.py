"""An environment file whose bottom is a real one: a dive's depth plus its echo sounder's readings
(`rov_mav.review.analysis.bottom_profile`) laid along a transect at a given speed, for the built-in vehicle
(`rov-mav sim-bridge --environment FILE`, or merged into a mission's environment). The log stays where it is; only
the rebuilt profile is written. Run:
    .venv/bin/python tools/seafloor_from_log.py LOG --out FILE [--speed 0.2] [--spacing 0.2] [--sounder ping]
e.g. with the SURFTRAK dive among the real logs (the folder ROVMAV_REAL_LOGS names):
    mohai-2023-10-18-09-55-06-surftrak.tlog.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import yaml

from rov_mav.review.analysis import bottom_profile
from rov_mav.review.dive_review import read_dive


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("log", type=Path, help="a .tlog or .BIN with depth and a down-looking rangefinder")
    parser.add_argument("--out", type=Path, required=True, help="the environment YAML to write")
    parser.add_argument("--speed", type=float, default=0.2, help="m/s the soundings are laid along at (default 0.2)")
    parser.add_argument("--spacing", type=float, default=0.2, help="m between the profile's points (default 0.2)")
    parser.add_argument("--sounder", default="ping", help="the echo sounder's preset in the file (default ping)")
    args = parser.parse_args(argv)
    if args.speed <= 0 or args.spacing <= 0:
        parser.error("--speed and --spacing must be positive")
    _, dive = read_dive(args.log)
    profile = bottom_profile(dive, args.speed, args.spacing)
    if profile is None:
        print(f"{args.log}: no depth and rangefinder readings to rebuild a bottom from", file=sys.stderr)
        return 1
    block = {"environment": {"seafloor": {"profile": [[round(float(a), 3), round(float(b), 3)] for a, b in profile]},
                             "navigation": {"preset": "ideal", "echo_sounder": args.sounder}}}
    args.out.write_text(f"# the bottom of {args.log.name}, its soundings laid along a line at {args.speed:g} m/s "
                        f"(tools/seafloor_from_log.py)\n" + yaml.safe_dump(block, sort_keys=False))
    print(f"{args.out}: {len(profile)} points over {profile[-1, 0]:.1f} m, bottom {profile[:, 1].min():.2f}-"
          f"{profile[:, 1].max():.2f} m deep")
    return 0


if __name__ == "__main__":
    sys.exit(main())
