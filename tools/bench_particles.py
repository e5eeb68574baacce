"""Benchmark: CPU per particle-step of the compiled closed loop, every controller, beside a plain C baseline.

One PSO iteration's batch: 100 particles (the shipped gains of each controller, each scaled by U(0.8, 1.2)) x 60 s
at 100 Hz on the line, the tuning problem as `rov-mav tune` builds it (tracking cost, saturation cut-off). Measured
in one run, process CPU time / particle-steps simulated, min and median of --repeats:
  1. C: tools/particle_loop.c, the report's law with constant-rate adaptation and the RK4 plant written in plain C,
     compiled now with the system compiler (cc -O3 -march=native, one thread) and called through ctypes on the same
     packed arrays; first checked against simulate_batch on one run (final state and cost);
  2. ours, one thread (`TuningProblem.run`), for every controller kind;
  3. ours on the 2-thread backend (`TuningProblem.costs` on `ThreadBackend`);
  4. the wall and CPU time of one robust tune iteration (the 7 scenarios of missions/scenarios/robust.yaml x 100
     particles) on 2 threads; times 100 iterations: the paper-scale robust tune (CPU / 2: on 2 cores to itself);
     beside it the C loop on one thread flying the same scenarios' particle-steps, and ours / C per particle-step.
Run:  .venv/bin/python tools/bench_particles.py [--repeats 5] [--figure PNG]
"""

from __future__ import annotations

import argparse
import ctypes
import os
import shutil
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

import particles_figure
from bench_tune import CountingBackend
from rov_mav.control.controller import KINDS, load_settings
from rov_mav.mission.missions import load_mission
from rov_mav.model import kernel
from rov_mav.model.vehicle import load_vehicle
from rov_mav.offline import loop_kernel, tuning
from rov_mav.offline.scenarios import load_scenarios, nominal

ROOT = Path(__file__).resolve().parents[1]
C_SOURCE = Path(__file__).with_name("particle_loop.c")
PARTICLES = 100
ITERATIONS = 100          # paper scale (Sec. IV.i)
TARGET_NS = 400           # issue 11: CPU per particle-step, every controller
TARGET_TUNE_S = 90        # issue 11: robust 7-scenario paper-scale tune on 2 cores
TARGET_RATIO = 0.75       # issue 31: the paper-scale tune's particle-steps at most 0.75x the C loop's, one thread each
AGREEMENT = 1e-6


def compile_c(workdir: Path):
    """The C baseline as a shared library, or None (with the reason printed) when no C compiler is here."""
    compiler = shutil.which("cc") or shutil.which("gcc")
    if compiler is None:
        print("C baseline: no C compiler (cc, gcc) on this machine; the C column is skipped")
        return None
    layout = {name: getattr(kernel, name) for name in dir(kernel) if name[:2] in ("P_", "E_")}
    layout.update(MAX_TILT=loop_kernel.MAX_TILT, MAX_SPEED=loop_kernel.MAX_SPEED,
                  DIVERGED_COST=loop_kernel.DIVERGED_COST)
    library = workdir / "particle_loop.so"
    command = [compiler, "-O3", "-march=native", "-shared", "-fPIC", *(f"-D{k}={v!r}" for k, v in layout.items()),
               "-o", str(library), str(C_SOURCE), "-lm"]
    done = subprocess.run(command, capture_output=True, text=True)
    if done.returncode != 0:
        print(f"C baseline: {compiler} failed ({done.stderr.strip().splitlines()[-1:]}); the C column is skipped")
        return None
    print(f"C baseline: {' '.join(command[:4])} {C_SOURCE.name} (one thread)")
    lib = ctypes.CDLL(str(library))
    lib.run_batch.restype = None
    return lib


def c_run(lib, problem: tuning.TuningProblem, params: np.ndarray, scenario: np.ndarray | None = None):
    """The C closed loop of each parameter row in its scenario of problem (scenario (n,); None: scenario 0):
    (cost, steps done, final state)."""
    n = params.shape[0]
    n_steps = problem.ref.shape[0] - 1
    scenario = np.zeros(n, dtype=np.int64) if scenario is None else scenario
    cost, steps, x_end = np.zeros(n), np.zeros(n, dtype=np.int64), np.zeros((n, 12))
    arrays = [np.ascontiguousarray(a, dtype=float) for a in (
        problem.plants[scenario], problem.envs[scenario], problem.model, params, problem.ref)]
    tail = [np.ascontiguousarray(a, dtype=float) for a in (
        problem.x0, problem.weights, problem.tau_ff, problem.tau_max, tuning.NO_LIMIT)]

    def ptr(a):
        return a.ctypes.data_as(ctypes.c_void_p)

    lib.run_batch(ctypes.c_long(n), ctypes.c_long(n_steps), *map(ptr, arrays), ctypes.c_double(problem.dt),
                  ctypes.c_long(1), *map(ptr, tail), ptr(cost), ptr(steps), ptr(x_end))
    return cost, steps, x_end


def ours_final_state(problem: tuning.TuningProblem, params: np.ndarray) -> tuple[float, np.ndarray]:
    """simulate_batch's cost and final true state of one run (row 0 of params) on scenario 0."""
    n_steps = problem.ref.shape[0] - 1
    logs = [np.zeros((1, n_steps + 1, 6)) for _ in range(6)]
    cost, steps = np.zeros(1), np.zeros(1, dtype=np.int64)
    loop_kernel.simulate_batch(problem.plants[:1], problem.envs[:1], problem.model, params[:1], *problem.controller,
                               problem.ref, problem.dt, 1, problem.x0, problem.seeds[:1], problem.nav_errors,
                               problem.nav_index[:1], problem.weights,
                               problem.tau_ff, problem.tau_max, tuning.NO_LIMIT, *logs, cost, steps)
    last = int(steps[0])
    return cost[0], np.concatenate([logs[0][0, last], logs[1][0, last]])


def timed(fn) -> tuple[float, float]:
    """fn() -> particle-steps simulated; (CPU ns per particle-step, wall s) of one call."""
    t0, cpu0 = time.perf_counter(), time.process_time()
    steps = fn()
    return (time.process_time() - cpu0) / steps * 1e9, time.perf_counter() - t0


def interleaved(cases: dict, repeats: int) -> dict:
    """Each case timed once per round, round after round, so that every case meets the same load: name -> list of
    (ns, wall) per round."""
    samples = {name: [] for name in cases}
    for _ in range(repeats):
        for name, fn in cases.items():
            samples[name].append(timed(fn))
    return samples


def c_case(lib, mission, model):
    """The C loop on the constant-rate batch, after checking it against simulate_batch on one run; None without a
    compiler."""
    if lib is None:
        return None
    settings = load_settings("constant")
    problem = tuning.build_problem(mission, settings, model, [nominal(mission.environment)], duration=60.0)
    params = particles(settings, PARTICLES)
    c_cost, _, c_end = c_run(lib, problem, params[:1])
    cost, end = ours_final_state(problem, params)
    gap = np.max(np.abs(c_end[0] - end))
    print(f"agreement on one run (constant): final state within {gap:.1e} (required {AGREEMENT:g}), "
          f"cost within {abs(c_cost[0] / cost - 1):.1e} relative\n")
    if not gap <= AGREEMENT:
        raise SystemExit("bench_particles: the C baseline disagrees with simulate_batch; not timing it")
    return lambda: int(c_run(lib, problem, params)[1].sum())


def our_cases(mission, model, backend) -> tuple[dict, dict]:
    """Per controller kind, the batch on one thread and on the backend (name -> call), and the share of the
    batch's particle-steps each kind simulates (the rest stop at saturation)."""
    cases, share = {}, {}
    for kind in KINDS:
        settings = load_settings(kind)
        problem = tuning.build_problem(mission, settings, model, [nominal(mission.environment)], duration=60.0)
        gains = particles(settings, PARTICLES)[:, :settings.gains.size]
        scenario = np.zeros(PARTICLES, dtype=np.int64)
        steps = problem.run(gains, scenario)[1]     # also the compile or cache load, outside the timing
        share[kind] = steps.sum() / (PARTICLES * (problem.ref.shape[0] - 1))
        counting = CountingBackend(backend)

        def on_backend(problem=problem, gains=gains, counting=counting):
            before = counting.ticks
            problem.costs(gains, counting)
            return counting.ticks - before

        cases[(kind, 1)] = lambda problem=problem, gains=gains, scenario=scenario: int(
            problem.run(gains, scenario)[1].sum())
        cases[(kind, backend.workers)] = on_backend
    return cases, share


def particles(settings, n: int) -> np.ndarray:
    """n parameter vectors: the shipped ones with the tuned gains scaled by U(0.8, 1.2) each (seed 0)."""
    scale = np.random.default_rng(0).uniform(0.8, 1.2, (n, settings.gains.size))
    return np.stack([settings.with_gains(g).vector for g in settings.gains * scale])


def figure_rows(samples: dict, ours: dict) -> list[dict]:
    """The C loop and each controller on one thread as `particles_figure` draws them: median ns, ours / C."""
    def row(name, controller):
        ratio = statistics.median(a / c for (a, _), (c, _) in zip(samples[name], samples["C"]))
        return {"controller": controller, "median": statistics.median(ns for ns, _ in samples[name]), "ratio": ratio}
    return [row("C", "C"), *(row(name, name[0]) for name in ours if name[1] == 1)]


def robust_tune(mission, model, robust, threads, repeats: int, lib) -> None:
    """The robust tune iteration (every scenario x PARTICLES) for each controller on the backend, its wall and CPU
    times, and, beside it, the C loop on one thread flying the same scenarios' particle-steps (constant-rate law, the
    shipped constant gains scaled as `particles`): the paper-scale tune's cost per particle-step, ours / C."""
    print(f"robust tune iteration: {len(robust)} scenarios x {PARTICLES} particles on {threads.workers} threads, "
          f"median of {repeats}; x {ITERATIONS} iterations = the paper-scale robust tune "
          f"(target <= {TARGET_TUNE_S} s on {threads.workers} cores)")
    c_ns = None
    if lib is not None:
        constant = load_settings("constant")
        problem = tuning.build_problem(mission, constant, model, robust, duration=60.0)
        params = np.tile(particles(constant, PARTICLES), (len(robust), 1))
        scenario = np.repeat(np.arange(len(robust)), PARTICLES)
        c_ns = statistics.median(timed(lambda: int(c_run(lib, problem, params, scenario)[1].sum()))[0]
                                 for _ in range(repeats))
        print(f"  C loop, one thread, the same {len(robust)} scenarios' particle-steps: {c_ns:.0f} ns per "
              f"particle-step (no sensor noise nor navigation error: it has none)")
    print(f"  {'controller':<10} {'wall':>7} {'CPU':>7} {'ns/step':>8} {'/C':>5} {'tune wall':>10} "
          f"{f'tune CPU/{threads.workers}':>11} {'tune wall / C one thread':>25}")
    worst = 0.0
    for kind in KINDS:
        settings = load_settings(kind)
        problem = tuning.build_problem(mission, settings, model, robust, duration=60.0)
        gains = particles(settings, PARTICLES)[:, :settings.gains.size]
        problem.run(gains[:1], np.zeros(1, dtype=np.int64))
        counting = CountingBackend(threads)
        walls, cpus = [], []
        for _ in range(repeats):
            t0, cpu0 = time.perf_counter(), time.process_time()
            problem.costs(gains, counting)
            walls.append(time.perf_counter() - t0)
            cpus.append(time.process_time() - cpu0)
        wall, cpu = statistics.median(walls), statistics.median(cpus)
        ns = sum(cpus) / counting.ticks * 1e9
        ratio = f"{ns / c_ns:5.2f}" if c_ns else f"{'-':>5}"
        worst = max(worst, ns / c_ns) if c_ns else worst
        c_tune = counting.ticks / repeats * c_ns * 1e-9 if c_ns else None
        versus = f"{wall / c_tune:25.2f}" if c_tune else f"{'-':>25}"
        verdict = "met" if wall * ITERATIONS <= TARGET_TUNE_S else "NOT met"
        print(f"  {kind:<10} {wall:6.2f}s {cpu:6.2f}s {ns:8.0f} {ratio} {wall * ITERATIONS:9.0f}s "
              f"{cpu / threads.workers * ITERATIONS:10.0f}s {versus}  {verdict}")
    print(f"  (tune CPU/{threads.workers}: what the tune would take with {threads.workers} cores to itself; /C: CPU per "
          f"particle-step against the C loop's on the same scenarios; tune wall / C one thread: the iteration's wall "
          f"time on {threads.workers} threads against the C loop's time for its particle-steps)")
    if c_ns:
        print(f"target <= {TARGET_RATIO} x C per particle-step for the paper-scale tune, every controller: "
              f"{'met' if worst <= TARGET_RATIO else 'NOT met'} (worst {worst:.2f})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--figure", type=Path, help="also draw the one-thread figures beside C (PNG)")
    args = parser.parse_args()

    mission, model = load_mission(ROOT / "missions" / "line.yaml"), load_vehicle()
    robust = load_scenarios(ROOT / "missions" / "scenarios" / "robust.yaml", mission.environment)
    print(f"load average before the run: {' '.join(f'{v:.2f}' for v in os.getloadavg())} "
          f"({os.cpu_count()} cores, shared)")
    print(f"batch: {PARTICLES} particles x 60 s at 100 Hz on the line (tracking cost, saturation cut-off); "
          f"CPU ns per particle-step, min / median of {args.repeats} rounds\n")

    with tempfile.TemporaryDirectory() as tmp, tuning.ThreadBackend(args.threads) as threads:
        cases = {}
        lib = compile_c(Path(tmp))
        c_fn = c_case(lib, mission, model)
        if c_fn is not None:
            cases["C"] = c_fn
        ours, share = our_cases(mission, model, threads)
        samples = interleaved({**cases, **ours}, args.repeats)

        def cells(name) -> str:
            ns, walls = zip(*samples[name])
            ratio = (f"{statistics.median(a / c for (a, _), (c, _) in zip(samples[name], samples['C'])):5.2f}"
                     if "C" in samples else f"{'-':>5}")
            return f"{min(ns):7.0f} {statistics.median(ns):7.0f} {statistics.median(walls):6.2f}s {ratio}"

        print(f"{'':<14} {'one thread':^29}   {f'{args.threads} threads':^29}")
        print(f"{'controller':<14} {'min ns':>7} {'median':>7} {'wall':>7} {'/C':>5}   {'min ns':>7} {'median':>7} "
              f"{'wall':>7} {'/C':>5}   simulated")
        if "C" in samples:
            print(f"{'C (constant)':<14} {cells('C')}")
        for kind in KINDS:
            print(f"{kind:<14} {cells((kind, 1))}   {cells((kind, args.threads))}   {share[kind]:.0%}")
        print("(/C: median over the rounds of ours / C in the same round; simulated: the share of the batch's "
              "particle-steps run, the rest stopped at saturation)")
        if args.figure and "C" in samples:
            particles_figure.draw(figure_rows(samples, ours), args.figure)
        worst = max(min(ns for ns, _ in samples[name]) for name in ours)
        print(f"target <= {TARGET_NS} ns CPU per particle-step for every controller: "
              f"{'met' if worst <= TARGET_NS else 'NOT met'} (worst min {worst:.0f} ns)")
        if "C" in samples:
            ratio = max(row["ratio"] for row in figure_rows(samples, ours)[1:])
            print(f"target <= {TARGET_RATIO} x C per particle-step on one thread, every controller: "
                  f"{'met' if ratio <= TARGET_RATIO else 'NOT met'} (worst median ratio {ratio:.2f})")
        print()

        robust_tune(mission, model, robust, threads, args.repeats, lib)
    print(f"load average after the run: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
