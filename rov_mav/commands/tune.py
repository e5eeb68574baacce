"""`rov-mav tune`: PSO tuning of a controller's gains (the report's 12 gains k1, k2: Sec. II.v, Eqs. 2.30-2.33; the
tuned groups of pid, smc, ismc) on a mission, optionally robust over scenarios, in process or on a Dask cluster."""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np
import yaml

from rov_mav.commands.arguments import (
    cluster_address,
    count,
    mission_file,
    number,
    output_file,
    output_folder,
    require_writable,
    scenarios_file,
    seed,
)
from rov_mav.commands.common import (
    MISSION_HELP,
    add_controller_options,
    add_plan_options,
    add_rerun_option,
    check_rerun_output,
    controller_settings,
    load_mission,
    navigation_errors,
    progress_bar,
    rerun_recording,
)
from rov_mav.control.controller import ControllerSettings
from rov_mav.mission.metrics import trace_metrics
from rov_mav.mission.missions import MAX_DURATION, Mission
from rov_mav.model.vehicle import Vehicle, load_flown_vehicle
from rov_mav.offline import loop_kernel, pso, tuning
from rov_mav.offline.scenarios import load_scenarios, nominal
from rov_mav.offline.simulation import Trace, simulate

MAX_PARTICLES = 10_000         # the swarm's arrays and each iteration's batch of runs stay in memory
MAX_ITERATIONS = 100_000
MAX_THREADS = 256
coefficient = number(-10.0, 10.0)   # w, c1, c2: the usual values are 0.4-0.9 and 1.5-2


def bounds_pair(text: str) -> tuple[float, float]:
    """Parse 'LO,HI' with 0 < LO < HI, both finite (argparse type)."""
    try:
        lo, hi = (float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text}: not LO,HI") from None
    if not 0 < lo < hi < math.inf:
        raise argparse.ArgumentTypeError(f"{text}: need 0 < LO < HI, both finite (Eq. 2.33: gains > 0)")
    return lo, hi


def configure(p: argparse.ArgumentParser) -> None:
    defaults = pso.PSOOptions()
    p.description = ("Particle swarm optimization of the controller's gains (the report's law: k1, k2, Eqs. "
                     "2.30-2.33; pid, smc, ismc: the groups their gains files list first): each iteration simulates the "
                     "whole swarm (x scenarios) through the compiled closed loop. Writes a gains YAML that "
                     "`simulate --gains` accepts, the convergence figure (Fig. IV-1) and the tuned gains' metrics "
                     "against the starting gains (default: the controller's shipped gains; `--gains report`: the "
                     "report's Eqs. 4.1-4.2) on the mission.")
    p.add_argument("mission", type=mission_file, help=MISSION_HELP + "; the report's tuning run is line")
    add_plan_options(p)
    add_controller_options(p)
    g = p.add_argument_group("swarm")
    g.add_argument("--particles", type=count(MAX_PARTICLES), default=defaults.particles,
                   help="swarm size (default 100)")
    g.add_argument("--iterations", type=count(MAX_ITERATIONS), default=defaults.iterations,
                   help="iterations; each evaluates the whole swarm (default 100)")
    g.add_argument("--budget", type=number(0.0, 1e6, low_open=True), metavar="S",
                   help="wall seconds the search may take: it ends after the last iteration that fits, with the best "
                        "found so far (default: all the iterations)")
    g.add_argument("--seed", type=seed, default=0, help="seed of the swarm's random numbers (default 0)")
    g.add_argument("--w", type=coefficient, default=defaults.w, help=f"inertia, Eq. 2.30 (default {defaults.w})")
    g.add_argument("--c1", type=coefficient, default=defaults.c1,
                   help=f"cognitive coefficient (default {defaults.c1})")
    g.add_argument("--c2", type=coefficient, default=defaults.c2, help=f"social coefficient (default {defaults.c2})")
    g.add_argument("--velocity-clamp", type=number(0.0, 1.0, low_open=True), default=defaults.velocity_clamp,
                   metavar="F",
                   help="max |velocity| per iteration as a fraction of the box width (default "
                        f"{defaults.velocity_clamp})")
    box = g.add_mutually_exclusive_group()
    box.add_argument("--bounds", type=bounds_pair, metavar="LO,HI",
                     help="the same box for all tuned gains (default: per controller; the report's law 0.1,10)")
    box.add_argument("--bounds-file", metavar="FILE",
                     help="per-gain box: YAML lower: {GROUP: [6 values]...}, upper: {...} for each tuned group "
                          "(the report's law: k1, k2)")
    c = p.add_argument_group("cost")
    c.add_argument("--cost", choices=tuning.COSTS, default="tracking",
                   help="tracking (default): 1 cm / 1 degree of error and a corrective wrench of one axis "
                        "capacity weigh the same; report: Eq. 2.32 with Q = R = I as printed")
    c.add_argument("--scenarios", type=scenarios_file, metavar="NAME|FILE",
                   help="score each particle over these scenarios: a shipped set's name (e.g. robust; `rov-mav "
                        "missions` lists them) or a scenarios YAML")
    c.add_argument("--aggregate", choices=tuning.AGGREGATES, default="mean",
                   help="combine scenario costs by their mean (default) or the worst case")
    c.add_argument("--duration", type=number(0.0, MAX_DURATION, low_open=True), metavar="S",
                   help=f"simulated seconds, at most {MAX_DURATION:g} (default: the mission's)")
    r = p.add_argument_group("compute")
    r.add_argument("--threads", type=count(MAX_THREADS), default=2, help="in-process threads (default 2)")
    r.add_argument("--cluster", type=cluster_address, metavar="ADDR",
                   help="evaluate on Dask: local:N (a LocalCluster of N processes) or tcp://HOST:PORT")
    o = p.add_argument_group("output")
    o.add_argument("--out", type=output_file, metavar="FILE",
                   help="gains YAML to write (default out/tune-MISSION/gains.yaml)")
    o.add_argument("--plot", type=output_folder, metavar="DIR",
                   help="folder for convergence.png and comparison.json (default: the folder of --out)")
    add_rerun_option(p)
    p.set_defaults(func=main)


def write_gains(path: Path, settings: ControllerSettings, header: str) -> None:
    """A gains YAML with every key `--gains` takes, so the tuned controller is reproduced exactly."""
    body = settings.as_yaml()
    path.parent.mkdir(parents=True, exist_ok=True)
    comments = "".join(f"# {line}\n" for line in header.splitlines())
    path.write_text(comments + yaml.safe_dump(body, sort_keys=False, default_flow_style=None))


def main(args: argparse.Namespace) -> int:
    mission = load_mission(args)
    start = controller_settings(args)
    model = load_flown_vehicle(args.vehicle)
    out = require_writable(args.out or f"out/tune-{mission.name}/gains.yaml", folder=False, option="--out")
    plot_dir = require_writable(args.plot or out.parent, folder=True, option="--plot")
    check_rerun_output(args, plot_dir / "tune.rrd")
    options = pso.PSOOptions(args.particles, args.iterations, args.w, args.c1, args.c2, args.velocity_clamp)
    lower, upper = _bounds(args, start)
    scenarios = (load_scenarios(args.scenarios, mission.environment) if args.scenarios
                 else [nominal(mission.environment)])
    problem = tuning.build_problem(mission, start, model, scenarios, args.cost, args.aggregate, args.duration,
                                   navigation_errors=navigation_errors)
    t0 = time.perf_counter()
    result, objective = _search(args, problem, options, lower, upper, start,
                                f"tuning {start.kind} on {mission.name}: {lower.size} gains, {options.particles} "
                                f"particles x {options.iterations} iterations x {len(scenarios)} scenario(s), "
                                f"{problem.ref.shape[0] - 1} ticks each, cost '{args.cost}', "
                                f"{args.cluster or f'{args.threads} threads'}")
    elapsed = time.perf_counter() - t0
    if result.best_cost >= loop_kernel.DIVERGED_COST:
        print(f"rov-mav tune: every particle diverged or saturated the thrusters (cost {loop_kernel.DIVERGED_COST:g}); "
              "no gains written: widen --bounds or check the mission's limits and the vehicle file", file=sys.stderr)
        return 1
    tuned = start.with_gains(result.best_position)
    write_gains(out, tuned, f"rov-mav tune {mission.name}: cost {args.cost} = {result.best_cost!r} "
                            f"({args.aggregate} over {len(scenarios)} scenario(s))\n"
                            f"{options.particles} particles x {options.iterations} iterations, seed {args.seed}, "
                            f"w {options.w}, c1 {options.c1}, c2 {options.c2}")
    plot_dir.mkdir(parents=True, exist_ok=True)
    from rov_mav.offline.plots import plot_convergence   # matplotlib loads only when a figure is drawn

    figure = plot_convergence(result.cost_history, result.position_history,
                              f"PSO on {mission.name} ({args.cost} cost)", plot_dir / "convergence.png")
    comparison = {"objective": {"cost": args.cost, "aggregate": args.aggregate,
                                "scenarios": [s.name for s in scenarios],
                                "start": float(objective[0]), "tuned": float(objective[1])},
                  "best_cost_per_iteration": result.cost_history.tolist(),
                  "elapsed_s": elapsed}
    traces = {}
    for label, settings in (("start", start), ("tuned", tuned)):
        comparison[label], traces[label] = _on_the_mission(mission, settings, model, problem, args.duration)
    (plot_dir / "comparison.json").write_text(json.dumps(comparison, indent=2) + "\n")
    _print_summary(comparison, tuned, result, elapsed, out, figure)
    _log_to_rerun(args, plot_dir / "tune.rrd", result, traces["tuned"], model, mission)
    return 0


def _bounds(args: argparse.Namespace, start) -> tuple[np.ndarray, np.ndarray]:
    """The search box: --bounds-file, else --bounds for every gain, else the family's defaults."""
    if args.bounds_file:
        return tuning.load_bounds(args.bounds_file, start.family)
    if args.bounds:
        n = start.family.n_tuned
        return np.full(n, args.bounds[0]), np.full(n, args.bounds[1])
    return start.family.default_bounds()


def _search(args: argparse.Namespace, problem, options, lower, upper, start, heading: str):
    """The swarm's search on the threads or the Dask cluster asked for, with a progress bar; (result, the objective
    of the starting and the best gains)."""
    if args.cluster:
        from rov_mav.offline.cluster import DaskBackend   # dask is optional: imported only when asked for
        backend = DaskBackend(args.cluster)
    else:
        backend = tuning.ThreadBackend(args.threads)
    print(heading)
    started = time.perf_counter()
    with backend, progress_bar(total=options.iterations, desc="tune", unit="it") as bar:
        def progress(iteration: int, best: float) -> bool:
            bar.set_postfix(best=f"{best:.5g}", refresh=False)
            bar.update(1)
            spent = time.perf_counter() - started
            return args.budget is not None and spent * (iteration + 1) / iteration > args.budget

        result = tuning.tune(problem, lower, upper, options, args.seed, backend, progress)
        if result.cost_history.size < options.iterations:
            bar.write(f"the --budget of {args.budget:g} s is spent: {result.cost_history.size} of "
                      f"{options.iterations} iterations run")
        return result, problem.costs(np.stack([start.gains, result.best_position]), backend)


def _log_to_rerun(args: argparse.Namespace, default_file: Path, result: pso.PSOResult, trace, model: Vehicle,
                  mission: Mission) -> None:
    """The convergence (timeline pso_iteration) and the tuned gains' run on the mission (vehicle_time)."""
    from rov_mav import telemetry

    target, recording = rerun_recording(args, default_file, trace.reference[:, :3], tuning=True)
    delivered = True
    if recording is not None:
        telemetry.send_convergence(recording, result.cost_history, result.position_history)
        telemetry.log_trace(recording, trace, model, telemetry.mission_events(mission, trace))
        delivered = telemetry.finish(recording)
    print(f"  rerun: {target.describe(delivered)}")


def _on_the_mission(mission: Mission, settings: ControllerSettings, model: Vehicle, problem: tuning.TuningProblem,
                    duration: float | None) -> tuple[dict, Trace]:
    """The gains, the metrics JSON of `simulate` and the cost of one recorded run on the mission as written,
    and that run."""
    trace = simulate(mission, settings, model, duration=duration, navigation_errors=navigation_errors)
    metrics = trace_metrics(mission.name, settings.kind, trace)
    gains = {name: settings.as_yaml()[name] for name in settings.family.tuned}
    return {**gains, "mission_cost": problem.trace_cost(trace) if trace.completed else None, **metrics}, trace


def _print_summary(comparison: dict, tuned: ControllerSettings, result: pso.PSOResult, elapsed: float, out: Path,
                   figure: Path) -> None:
    obj = comparison["objective"]
    print(f"best cost {result.best_cost:.6g} in {elapsed:.1f} s (start gains: {obj['start']:.6g})")
    for name in tuned.family.tuned:
        print(f"  {name} = {np.round(tuned.params[name], 3).tolist()}")
    print(f"  {'on the mission':<32}{'start':>12}{'tuned':>12}")
    rows = (("position error RMS (cm)", "rms_position_error_m", 100), ("  steady (cm)", "rms_position_error_steady_m",
            100), ("  max (cm)", "max_position_error_m", 100), ("attitude error RMS (deg)", "rms_attitude_error_rad",
            np.degrees(1.0)), ("control effort (N^2 s)", "control_effort", 1))
    for label, key, scale in rows:
        print(f"  {label:<32}{comparison['start'][key] * scale:>12.4g}{comparison['tuned'][key] * scale:>12.4g}")
    print(f"  gains: {out}  (use with --gains)")
    print(f"  figure: {figure}; comparison: {figure.parent / 'comparison.json'}")
