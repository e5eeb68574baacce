"""`rov-mav bench`: which controller tracks best, where, and how sure we are (the procedure: `rov_mav.offline.bench`).

Writes to --out: bench.md (the table), bench.json (every figure), gains/MISSION-CONTROLLER.yaml (the tuned gains,
`simulate --gains` takes them; MISSION-CONTROLLER-seedS.yaml per swarm seed with --tunes above 1),
errors-MISSION.png (box plots per controller) and rerun/CONTROLLER.rrd (one representative held-out run per
controller, in the telemetry layout)."""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path

from rov_mav.commands.arguments import (
    cluster_address,
    count,
    mission_file,
    output_folder,
    require_writable,
    scenarios_file,
    vehicle_file,
)
from rov_mav import shipped
from rov_mav.control.controller import KINDS

DEFAULT_MISSIONS = ("line", "square")      # shipped missions and scenario sets, by name (`rov-mav missions`)
DEFAULT_TRAINING = "robust_dive"
DEFAULT_HELD_OUT = "bench"
DEFAULT_BUDGET = (30, 20)
MAX_PARTICLES = 10_000
MAX_ITERATIONS = 100_000
MAX_SEEDS = 1000
MAX_TUNES = 100
MAX_THREADS = 256
BENCH_KINDS = tuple(KINDS)   # every controller with a law of ours (ardusub-guided flies only in `run`)


def controller_names(text: str) -> list[str]:
    """An argparse type: one or more controller names, comma-separated."""
    names = [n.strip() for n in text.split(",")]
    for name in names:
        if name not in BENCH_KINDS:
            raise argparse.ArgumentTypeError(f"{name or text!r}: unknown controller (choose from "
                                             f"{', '.join(BENCH_KINDS)})")
    return names


def budget(text: str) -> tuple[int, int]:
    """An argparse type: PARTICLESxITERATIONS, e.g. 30x20."""
    match = re.fullmatch(r"(\d{1,6})[xX](\d{1,6})", text.strip())
    if match is None:
        raise argparse.ArgumentTypeError(f"{text}: expected PARTICLESxITERATIONS, e.g. 30x20")
    particles, iterations = int(match.group(1)), int(match.group(2))
    if not (1 <= particles <= MAX_PARTICLES and 1 <= iterations <= MAX_ITERATIONS):
        raise argparse.ArgumentTypeError(f"{text}: particles from 1 to {MAX_PARTICLES}, iterations from 1 to "
                                         f"{MAX_ITERATIONS}")
    return particles, iterations


def configure(p: argparse.ArgumentParser) -> None:
    p.description = ("Each controller is PSO-tuned with the same budget on the training scenarios of each mission, "
                     "then flown on the held-out scenarios (model error, currents, waves, DVL-level noise, 5-10 Hz "
                     "delayed telemetry, thruster saturation) over N noise seeds. Writes bench.md (mean and 95 % "
                     "Student-t interval per controller x mission x scenario group), bench.json, the tuned gains, "
                     "box plots and a Rerun recording per controller to --out. With --tunes K each controller is "
                     "tuned K times (swarm seeds 0..K-1) and the intervals are over the tunes, so they hold the luck "
                     "of the tune as well as the noise's.")
    p.add_argument("--controllers", type=controller_names, nargs="+", metavar="NAME",
                   help=f"controllers to compare, space- or comma-separated (default: all: {', '.join(BENCH_KINDS)})")
    p.add_argument("--missions", nargs="+", type=mission_file, metavar="NAME|FILE",
                   help="shipped missions by name or mission files (YAML or .plan); `rov-mav missions` lists the "
                        f"shipped ones (default: {' '.join(DEFAULT_MISSIONS)})")
    p.add_argument("--scenarios", type=scenarios_file, metavar="NAME|FILE", default=DEFAULT_HELD_OUT,
                   help="held-out scenarios the controllers are judged on: a shipped set's name or a scenarios YAML "
                        f"(default {DEFAULT_HELD_OUT})")
    p.add_argument("--training", type=scenarios_file, metavar="NAME|FILE", default=DEFAULT_TRAINING,
                   help=f"training scenarios the controllers are tuned on (default {DEFAULT_TRAINING})")
    p.add_argument("--seeds", type=count(MAX_SEEDS), default=5,
                   help="noise seeds per held-out scenario (default 5)")
    p.add_argument("--tunes", type=count(MAX_TUNES), default=1, metavar="K",
                   help="independent tunes per controller and mission, swarm seeds 0..K-1, each flown on every "
                        "held-out run; with K > 1 each figure is the mean of the tunes' means and its interval is "
                        "over the tunes (default 1: one tune, intervals over the noise seeds)")
    p.add_argument("--tune-budget", type=budget, default=DEFAULT_BUDGET, metavar="PxI",
                   help="PSO particles x iterations per controller and mission, the same for all (default "
                        f"{DEFAULT_BUDGET[0]}x{DEFAULT_BUDGET[1]})")
    p.add_argument("--out", type=output_folder, default="out/bench", metavar="DIR",
                   help="output folder (default out/bench)")
    p.add_argument("--threads", type=count(MAX_THREADS), default=2, help="in-process threads (default 2)")
    p.add_argument("--cluster", type=cluster_address, metavar="ADDR",
                   help="tune on Dask: local:N (a LocalCluster of N processes) or tcp://HOST:PORT; the held-out "
                        "runs stay in process")
    p.add_argument("--vehicle", type=vehicle_file, metavar="NAME|FILE",
                   help="the controllers' vehicle model: a shipped vehicle's name or a vehicle YAML (default: "
                        "bluerov2_heavy)")
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    from rov_mav.commands.common import navigation_errors, progress_bar
    from rov_mav.config import ConfigError
    from rov_mav.mission.loader import load
    from rov_mav.model.vehicle import load_flown_vehicle
    from rov_mav.offline import bench, pso, tuning
    from rov_mav.offline.scenarios import load_scenarios

    controllers = list(dict.fromkeys(n for group in (args.controllers or [list(BENCH_KINDS)]) for n in group))
    missions = [load(path) for path in (args.missions or [mission_file(name) for name in DEFAULT_MISSIONS])]
    names = [m.name for m in missions]
    if len(set(names)) < len(names):
        raise ConfigError(f"--missions: two missions named '{next(n for n in names if names.count(n) > 1)}'")
    training = {m.name: load_scenarios(args.training, m.environment) for m in missions}
    held_out = {m.name: load_scenarios(args.scenarios, m.environment) for m in missions}
    model = load_flown_vehicle(args.vehicle)
    out = require_writable(args.out, folder=True, option="--out")
    particles, iterations = args.tune_budget
    options = pso.PSOOptions(particles, iterations)
    compute = args.cluster or f"{args.threads} threads"
    runs = sum(len(held_out[m.name]) for m in missions) * args.seeds * len(controllers) * args.tunes
    tunes = "" if args.tunes == 1 else f" {args.tunes} times (swarm seeds 0-{args.tunes - 1})"
    print(f"bench: {', '.join(controllers)} on {', '.join(names)}: tuning {particles}x{iterations}{tunes} over "
          f"{len(training[names[0]])} training scenarios, then {runs} held-out runs ({args.seeds} seeds), {compute}")

    if args.cluster:
        from rov_mav.offline.cluster import DaskBackend  # dask is optional: imported only when asked for
        backend = DaskBackend(args.cluster)
    else:
        backend = tuning.ThreadBackend(args.threads)
    total = bench.work(missions, controllers, training, held_out, args.seeds, options, args.tunes)
    with backend, progress_bar(total=total, desc="bench", unit="tick", unit_scale=True) as bar:
        result = bench.run_bench(missions, controllers, model, training, held_out, args.seeds, options, backend,
                                 args.threads, bar.update, args.tunes, navigation_errors)
    interval = "" if args.tunes == 1 else f", over the {args.tunes} tunes"
    settings = {"controllers": controllers, "missions": names, "training": shipped.label(args.training),
                "held_out": shipped.label(args.scenarios),
                "seeds": args.seeds, "particles": particles, "iterations": iterations, "tunes": args.tunes,
                "swarm_seeds": list(bench.swarm_seeds(args.tunes)),
                "interval": f"Student-t {bench.LEVEL:.0%} interval of the mean{interval}",
                "voltage_v": bench.VOLTAGE, "compute": compute}
    _write(out, result, settings, missions, model, held_out)
    return 0


def _write(out: Path, result, settings: dict, missions, model, held_out) -> None:
    from rov_mav.commands.tune import write_gains
    from rov_mav.offline import bench
    from rov_mav.offline.bench_report import COLUMNS, groups, leader, markdown
    from rov_mav.offline.plots import plot_bench

    out.mkdir(parents=True, exist_ok=True)
    (out / "bench.json").write_text(json.dumps(bench.result_document(result, settings), indent=1) + "\n")
    (out / "bench.md").write_text(markdown(result, settings))
    for t in result.tuned:
        name = f"{t.mission}-{t.settings.kind}" + ("" if settings["tunes"] == 1 else f"-seed{t.swarm_seed}")
        write_gains(out / "gains" / f"{name}.yaml", t.settings,
                    f"rov-mav bench: {t.settings.kind} tuned on {t.mission} (swarm seed {t.swarm_seed}), "
                    f"training cost {t.training_cost!r}")
    figures = []
    for m in missions:
        done = [r for r in result.runs if r.mission == m.name and r.completed]
        panels = {label: {c: [getattr(r, f) * scale for r in done if r.controller == c]
                          for c in settings["controllers"]}
                  for f, label, scale in COLUMNS if f != "saturation_fraction"}
        figures.append(plot_bench(panels, f"{m.name}: held-out runs ({settings['seeds']} seeds per scenario)",
                                  out / f"errors-{m.name}.png"))
    recordings = _record(out / "rerun", result, missions[0], model, held_out[missions[0].name])
    print(f"bench: {result.timing['total_s']:.0f} s (tuning {result.timing['tune_s']:.0f} s, held-out runs "
          f"{result.timing['evaluate_s']:.0f} s); who tracks best (fewest failures, then RMS position error):")
    for m in missions:
        for group in groups(result.summaries, m.name):
            lead = leader(result.summaries, result.runs, m.name, group)
            best = ("every run diverged" if lead is None else
                    f"{lead[0].controller}: {lead[0].figures['rms_position_m'].mean * 100:.3g} cm, "
                    f"{lead[0].failures}/{lead[0].runs} failed" + (" (clear)" if lead[1] else ""))
            print(f"  {m.name:<10} {group:<14} {best}")
    print(f"  table: {out / 'bench.md'}; all figures: {out / 'bench.json'}; plots: "
          f"{', '.join(str(f) for f in figures)}")
    print(f"  gains: {out / 'gains'}; rerun: {', '.join(str(r) for r in recordings)}")


def _record(folder: Path, result, mission, model, held_out) -> list[Path]:
    """One Rerun recording per controller: its median held-out run on the first mission (over every tune)."""
    from rov_mav import telemetry
    from rov_mav.commands.common import navigation_errors
    from rov_mav.offline import bench

    scenarios = {s.name: s for s in held_out}
    tuned = {(t.settings.kind, t.swarm_seed): t for t in result.tuned if t.mission == mission.name}
    paths = []
    for kind in dict.fromkeys(kind for kind, _ in tuned):
        run = bench.representative(result.runs, kind, mission.name)
        if run is None:
            continue
        trace, _ = bench.replay(mission, tuned[kind, run.tune].settings, model, scenarios[run.scenario], run.seed,
                                navigation_errors)
        path = folder / f"{kind}.rrd"
        rec = telemetry.open_recording(telemetry.RerunTarget("save", str(path)),
                                       telemetry.default_blueprint(trace.reference[:, :3]))
        telemetry.log_trace(rec, trace, model, [(0.0, f"{kind} on {mission.name}: held-out {run.scenario}, seed "
                                                      f"{run.seed}, tune {run.tune} (median RMS position error)",
                                                 "INFO")] + telemetry.mission_events(mission, trace))
        telemetry.finish(rec)
        paths.append(path)
    return paths
