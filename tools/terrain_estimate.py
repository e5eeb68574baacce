"""How well an altitude leg's surface estimate (`rov_mav.mission.terrain.SurfaceEstimate`) knows the true bottom
under a Ping-like echo sounder (`sim_bridge.navigation.echo_sounder`), with no vehicle in the way: a sounder carried
exactly 1 m above a bottom at 0.2 m/s for 300 s, the estimate's error against the bottom straight below, RMS and
max over several seeds, for the gate's counts side by side, with and without false locks. Run:
    .venv/bin/python tools/terrain_estimate.py [--seeds N] [--relief M]
"""

from __future__ import annotations

import argparse

import numpy as np

from rov_mav.mission import terrain
from rov_mav.model.seafloor import Surface
from sim_bridge.navigation.echo_sounder import EchoSounder

STEP = 0.02                      # s between the carrier's positions
SPEED = 0.2                      # m/s
HEIGHT = 1.0                     # m


def errors(floor: Surface, gate: int, seed: int, false_locks: float, seconds: float) -> np.ndarray:
    """The estimate's error (m) against the bottom below, every STEP while it has the bottom."""
    terrain.GATE_COUNT = gate
    sounder = EchoSounder({"preset": "ping", "false_lock_probability": false_locks}, seed, floor, None)
    estimate = terrain.SurfaceEstimate()
    out = []
    for k in range(int(seconds / STEP)):
        t = k * STEP
        north = SPEED * t
        bottom = floor.depth_at(north, 0.0)
        depth = bottom - HEIGHT
        for reading in sounder.sample(t, np.array([north, 0.0, depth, 0.0, 0.0, 0.0]), np.zeros(6)):
            quality = reading.confidence if reading.confidence > 1 else 0          # as the link carries it
            estimate.update(t, depth, reading.distance, quality)
        if not estimate.lost(t):
            out.append(estimate.at(t)[0] - bottom)
    return np.array(out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=6)
    parser.add_argument("--relief", type=float, default=0.1, help="m RMS of the bottom's relief (default 0.1)")
    parser.add_argument("--seconds", type=float, default=300.0)
    args = parser.parse_args()
    floor = Surface(depth=8.0, slope=0.1, relief=args.relief, wavelength=3.0, seed=1)
    chosen = terrain.GATE_COUNT
    print(f"bottom: 10 % slope, {args.relief:g} m RMS relief; sounder 1 m up at {SPEED:g} m/s, {args.seconds:g} s, "
          f"{args.seeds} seeds; the estimate's error against the bottom below (cm)")
    print(f"{'false locks':>12} {'gate':>5} {'RMS mean':>9} {'RMS worst':>10} {'max worst':>10}")
    for false_locks in (0.0, 0.001, 0.005):
        for gate in (5, 10, 20):
            runs = [errors(floor, gate, seed, false_locks, args.seconds) for seed in range(args.seeds)]
            rms = [np.sqrt(np.mean(e ** 2)) * 100 for e in runs]
            worst = max(np.abs(e).max() for e in runs) * 100
            mark = "  <- shipped" if gate == chosen else ""
            print(f"{false_locks:>12g} {gate:>5d} {np.mean(rms):>9.1f} {max(rms):>10.1f} {worst:>10.0f}{mark}")
    terrain.GATE_COUNT = chosen


if __name__ == "__main__":
    main()
