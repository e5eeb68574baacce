"""Benchmark: the report's PSO tuning at paper scale (Sec. IV.i), and the same work driven the usual way.

Paper scale: 100 particles x 100 iterations, each particle a 60 s closed-loop run on the line (Eq. 3.1) at the
100 Hz control rate with the fuzzy adaptation in the loop. Measured in one run:
  1. compile / cache load of the kernel, separately;
  2. our tuner (`rov_mav.offline.tuning`, the swarm as batches on 2 threads), the whole tune;
  3. pyswarms' GlobalBestPSO (same w, c1, c2, bounds, velocity clamp) whose objective loops over the particles,
     one call of the same compiled simulation per particle: measured for --baseline-iterations, extrapolated;
  4. the same, but the per-particle simulation written with NumPy from the readable model and law
     (rov_mav.model.dynamics, rov_mav.control.law, the exact fuzzy rates): how a script port of the Simulink model runs;
     measured on a few short runs and extrapolated per particle-tick;
  5. a floor for one particle-tick: the compiled RK4 plant step alone (4 model evaluations, no law, no
     adaptation, no cost), the part of a tick no implementation can skip.
Run:  .venv/bin/python tools/bench_tune.py [--baseline-iterations 10]
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np
from numba import njit

from rov_mav.control import law
from rov_mav.control.controller import load_settings
from rov_mav.mission.missions import load_mission
from rov_mav.model import dynamics, kernel
from rov_mav.model.vehicle import load_vehicle
from rov_mav.offline import pso, tuning
from rov_mav.offline.scenarios import nominal
from rov_mav.offline.simulation import simulate

ROOT = Path(__file__).resolve().parents[1]
BOX = (np.full(12, 0.1), np.full(12, 10.0))


class CountingBackend:
    """Wraps a backend's map_runs and counts the closed-loop ticks actually simulated."""

    def __init__(self, backend):
        self.backend, self.workers, self.ticks = backend, backend.workers, 0

    def map_runs(self, problem, batches):
        runs = self.backend.map_runs(problem, batches)
        self.ticks += sum(int(steps.sum()) for _, steps in runs)
        return runs


def pyswarms_tune(objective, options: pso.PSOOptions, iterations: int, seed: int):
    """pyswarms' GlobalBestPSO with our options; returns (wall, CPU) seconds."""
    import pyswarms

    np.random.seed(seed)   # pyswarms draws from numpy's global generator
    width = BOX[1] - BOX[0]
    opt = pyswarms.single.GlobalBestPSO(
        n_particles=options.particles, dimensions=12, bounds=BOX,
        options={"w": options.w, "c1": options.c1, "c2": options.c2}, bh_strategy="nearest",
        velocity_clamp=(-options.velocity_clamp * width[0], options.velocity_clamp * width[0]))
    t0, cpu0 = time.perf_counter(), time.process_time()
    opt.optimize(objective, iters=iterations, verbose=False)
    return time.perf_counter() - t0, time.process_time() - cpu0


def numpy_run(problem: tuning.TuningProblem, model, settings, gains: np.ndarray, n_ticks: int) -> float:
    """One closed-loop run tick by tick in NumPy (matrix-form model and law, exact fuzzy rates, RK4): the cost."""
    ref, dt = problem.ref, problem.dt
    tau_d = problem.envs[0, kernel.E_DIST:kernel.E_DIST + 6]
    x, tau_hat, total = problem.x0.copy(), np.zeros(6), 0.0
    k1, k2 = gains[:6], gains[6:]

    def f(state, tau):
        eta, nu = state[:6], state[6:]
        return np.concatenate([dynamics.jacobian(eta) @ nu, dynamics.acceleration(model, eta, nu, tau + tau_d)])

    for k in range(n_ticks):
        tau, s = law.control_law(model, k1, k2, x[:6], x[6:], ref[k], tau_hat)
        grad = law.adaptation_direction(model, x[:6], s)
        tau_hat = np.clip(tau_hat + dt * settings.fuzzy.rates(grad) * grad, -settings.d_max, settings.d_max)
        e = law.tracking_error(x[:6], ref[k, :6])
        u = tau - problem.tau_ff[k]
        total += (problem.weights[0] @ s**2 + problem.weights[1] @ e**2 + problem.weights[2] @ u**2) * dt
        a = f(x, tau)
        b = f(x + 0.5 * dt * a, tau)
        c = f(x + 0.5 * dt * b, tau)
        d = f(x + dt * c, tau)
        x = x + dt / 6.0 * (a + 2 * b + 2 * c + d)
    return total


@njit(cache=True)
def plant_only(plant, env, x0, tau, n_ticks, dt):
    """The floor: n_ticks RK4 steps of the plant with a fixed wrench."""
    x, ws = x0.copy(), np.zeros(80)
    for k in range(n_ticks):
        kernel.rk4_step(plant, env, x, tau, k * dt, dt, ws)
    return x


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline-iterations", type=int, default=10,
                        help="pyswarms iterations to time with the compiled per-particle loop (default 10)")
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()

    mission, model, settings = load_mission(ROOT / "missions" / "line.yaml"), load_vehicle(), load_settings("fuzzy")
    problem = tuning.build_problem(mission, settings, model, [nominal(mission.environment)], duration=60.0)
    n_ticks = problem.ref.shape[0] - 1
    options = pso.PSOOptions(particles=100, iterations=100)

    t0 = time.perf_counter()
    problem.run(settings.gains[None], np.zeros(1, dtype=np.int64))
    print(f"compile or cache load of the kernel (first call): {time.perf_counter() - t0:.2f} s")

    with tuning.ThreadBackend(args.threads) as threads:
        backend = CountingBackend(threads)
        load = os.getloadavg()[0]
        t0, cpu0 = time.perf_counter(), time.process_time()
        ours = tuning.tune(problem, *BOX, options, 0, backend)
        wall, cpu = time.perf_counter() - t0, time.process_time() - cpu0
    evaluations = options.particles * options.iterations
    tick_cpu = cpu / backend.ticks
    print(f"\nours: {options.particles} particles x {options.iterations} iterations x {n_ticks} ticks "
          f"(60 s at 100 Hz, fuzzy adaptation), {args.threads} threads")
    print(f"  wall {wall:.1f} s   (target <= 60 s)   best cost {ours.best_cost:.5g}")
    print(f"  CPU {cpu:.1f} s: {cpu / wall:.2f} of {args.threads} cores on average (load average before the run "
          f"{load:.2f}: other processes share the machine); on {args.threads} idle cores: "
          f"~{cpu / args.threads:.0f} s")
    print(f"  {backend.ticks / (evaluations * n_ticks):.1%} of the {evaluations * n_ticks:.3g} particle-ticks "
          f"simulated (the rest: runs stopped at saturation or divergence); {tick_cpu * 1e9:.0f} ns CPU per "
          f"particle-tick")

    def compiled_loop(x):
        return np.array([problem.run(x[i:i + 1], np.zeros(1, dtype=np.int64))[0][0] for i in range(len(x))])

    def simulate_loop(x):
        return np.array([problem.trace_cost(simulate(mission, settings.with_gains(g), model, duration=60.0))
                         for g in x])

    print(f"\npyswarms GlobalBestPSO, objective = a loop over the particles (one core), {args.baseline_iterations} "
          f"iterations timed, extrapolated to {options.iterations}:")
    for label, objective in (("the compiled kernel, one call per particle", compiled_loop),
                             ("rov_mav.offline.simulation.simulate() per particle (recorded run)", simulate_loop)):
        seconds, cpu_b = pyswarms_tune(objective, options, args.baseline_iterations, 0)
        full, full_cpu = (v * options.iterations / args.baseline_iterations for v in (seconds, cpu_b))
        print(f"  {label}: {full:.0f} s wall ({full_cpu:.0f} s CPU) -> ours {full / wall:.1f}x faster in wall time, "
              f"{full_cpu / cpu:.2f}x in CPU time")

    short = 200
    sample = settings.gains * np.random.default_rng(0).uniform(0.8, 1.2, (3, 12))
    t0 = time.process_time()
    slow = [numpy_run(problem, model, settings, g, short) for g in sample]
    numpy_tick = (time.process_time() - t0) / (len(sample) * short)
    numpy_full = numpy_tick * evaluations * n_ticks
    check = tuning.build_problem(mission, settings, model, [nominal(mission.environment)], duration=short * 0.01)
    fast = check.run(sample, np.zeros(len(sample), dtype=np.int64))[0]
    print(f"  the same model and law in NumPy, tick by tick: {numpy_tick * 1e6:.0f} us CPU per particle-tick "
          f"(measured on {len(sample)} x {short} ticks; costs within {np.max(np.abs(slow / fast - 1)):.1e} of the "
          f"kernel's) -> {numpy_full / 3600:.1f} h at paper scale -> ours {numpy_full / wall:,.0f}x faster")

    plant, env = problem.plants[0], problem.envs[0]
    tau = tuning.feedforward(model, problem.ref[:2])[0]
    plant_only(plant, env, problem.x0, tau, 10, 0.01)
    steps = 200_000
    t0 = time.process_time()
    plant_only(plant, env, problem.x0, tau, steps, 0.01)
    floor = (time.process_time() - t0) / steps
    print(f"\nfloor: the compiled RK4 plant step alone (4 model evaluations) {floor * 1e9:.0f} ns CPU per tick; "
          f"our full particle-tick (law, fuzzy adaptation, noise, cost, plant) {tick_cpu * 1e9:.0f} ns = "
          f"{tick_cpu / floor:.2f}x the floor")


if __name__ == "__main__":
    main()
