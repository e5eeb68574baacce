"""Benchmark: closed-loop simulation speed of the compiled kernel (one vehicle and a 100-vehicle batch).

Prints the compile/cache-load time separately, then the best of several repeats for a 60 s run at the 100 Hz
control rate with fuzzy adaptation on the report's line, and the per-vehicle-step cost. Run:
    .venv/bin/python tools/bench_simulation.py
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from rov_mav.control.controller import load_settings
from rov_mav.mission.missions import load_mission
from rov_mav.model.vehicle import load_vehicle
from rov_mav.offline import loop_kernel
from rov_mav.offline.simulation import NO_NAVIGATION

ROOT = Path(__file__).resolve().parents[1]


def batch_runner(n: int, duration: float = 60.0, dt: float = 0.01):
    vehicle = load_vehicle()
    mission = load_mission(ROOT / "missions" / "line.yaml")
    settings = load_settings("fuzzy")
    args = settings.kernel_arguments()
    ref = mission.sampled_reference(dt, duration)
    rng = np.random.default_rng(0)
    gains = np.stack([settings.with_gains(g).vector for g in settings.gains * rng.uniform(0.8, 1.2, (n, 12))])
    plant = np.tile(vehicle.packed(), (n, 1))
    env = np.tile(mission.environment.packed(), (n, 1))
    x0 = np.concatenate([mission.start_pose, np.zeros(6)])
    empty = np.zeros((n, 0, 6))
    cost, steps = np.zeros(n), np.zeros(n, dtype=np.int64)

    def run():
        loop_kernel.simulate_batch(plant, env, vehicle.packed(), gains, *args, ref, dt, 1, x0,
                              np.zeros(n, dtype=np.int64), NO_NAVIGATION, np.zeros(n, dtype=np.int64),
                              *loop_kernel.printed_cost(ref),
                              empty, empty, empty, empty, empty, empty, cost, steps)
        return cost

    return run, ref.shape[0] - 1


def best_of(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    t0 = time.perf_counter()
    one, n_steps = batch_runner(1)
    one()
    print(f"first call (compile or cache load, plus setup): {time.perf_counter() - t0:.2f} s")
    single = best_of(one, 7)
    hundred, _ = batch_runner(100)
    batch = best_of(hundred, 3)
    print(f"one vehicle, 60 s at 100 Hz ({n_steps} ticks):  {single * 1e3:7.1f} ms"
          f"  ({single / n_steps * 1e6:.2f} us per tick)   target <= 50 ms")
    print(f"100 vehicles, 60 s at 100 Hz (one core):      {batch * 1e3:7.1f} ms"
          f"  ({batch / (100 * n_steps) * 1e6:.2f} us per vehicle-tick)   target <= 500 ms")
    print(f"faster than real time: {60.0 / single:,.0f}x (one vehicle), {6000.0 / batch:,.0f}x (batch, vehicle-s/s)")


if __name__ == "__main__":
    main()
