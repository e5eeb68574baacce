"""The bench: controllers tuned alike on training scenarios, then judged on held-out ones over seeds, with intervals.

Procedure (`run_bench`): for each mission and controller, PSO (`tuning.tune`, the same budget, swarm seeds, cost
and bounds rules for all: the family's default box, the tracking cost, the mean over the training scenarios) from the
controller's shipped non-tuned parameters, once per swarm seed 0..tunes-1 (independent tunes: where the swarm lands
is itself a draw); then every held-out scenario x seed is flown with each tune's gains by the
same `simulate` any user can call (`replay`), the plant clipping the commanded wrench per axis to the capacity of its
thrusters (`tuning.wrench_capacity` at the scenario's or the mission's max thrust). Per run (`run_figures`): RMS and
max position error, RMS attitude error, electrical energy (the wrench the plant received, allocated to the thrusters
by the pseudo-inverse, each thrust to its current by the T200 data at VOLTAGE), the fraction of ticks with a
saturated command, and whether the run diverged. Per controller x mission x scenario group (and all groups): the
mean of each figure over the completed runs with a Student-t 95 % interval (`mean_interval`), and the failures;
between two controllers, the t-interval of their paired difference over the same scenarios and seeds
(`paired_difference`). With several tunes the unit of replication is the tune (a two-stage sample: the runs of one
tune share its gains, so they are not independent draws of how the law does once tuned): a figure is the mean of
the tunes' means with its interval over those means (`tune_interval`), and a paired difference is each tune's mean
difference, its interval over the tunes.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass

import numpy as np
from scipy import stats

from rov_mav.control.controller import ControllerSettings, load_settings
from rov_mav.mission.metrics import tracking_errors
from rov_mav.mission.missions import Mission
from rov_mav.model.thrusters import allocation_matrix, thruster_curve
from rov_mav.model.vehicle import Vehicle
from rov_mav.offline import pso, tuning
from rov_mav.offline.scenarios import Scenario
from rov_mav.offline.simulation import CONTROL_DT, NavigationErrors, Trace, simulate

VOLTAGE = 16.0          # V: a charged 4S pack, the runner's default before the vehicle reports one
LEVEL = 0.95            # the intervals' confidence
FIRST_SWARM_SEED = 0    # the tunes' swarm seeds are 0, 1, ... for every controller alike
FIGURES = ("rms_position_m", "max_position_m", "rms_attitude_rad", "energy_wh", "saturation_fraction")
ALL_GROUPS = "all"


@dataclass(frozen=True)
class Tuned:
    """A controller tuned for a mission with one swarm seed: its settings, the training objective reached, the time it
    took."""

    mission: str
    settings: ControllerSettings
    training_cost: float
    elapsed_s: float
    swarm_seed: int = FIRST_SWARM_SEED


@dataclass(frozen=True)
class RunFigures:
    """One held-out run's figures (`FIGURES`) and where it came from (`tune`: the swarm seed of the gains flown)."""

    controller: str
    mission: str
    scenario: str
    group: str
    seed: int
    completed: bool
    rms_position_m: float
    max_position_m: float
    rms_attitude_rad: float
    energy_wh: float
    saturation_fraction: float
    tune: int = FIRST_SWARM_SEED


@dataclass(frozen=True)
class Interval:
    mean: float
    low: float
    high: float


@dataclass(frozen=True)
class Summary:
    """A controller on a mission over a scenario group: runs, failures and each figure's mean and interval over the
    completed runs."""

    controller: str
    mission: str
    group: str
    runs: int
    failures: int
    figures: dict[str, Interval]


def mean_interval(values: Sequence[float], level: float = LEVEL) -> Interval:
    """Sample mean and its Student-t interval at `level` (NaNs for no value; a zero-width interval for one)."""
    x = np.asarray(values, float)
    if x.size == 0:
        return Interval(math.nan, math.nan, math.nan)
    mean = float(x.mean())
    if x.size == 1:
        return Interval(mean, mean, mean)
    half = float(stats.t.ppf(0.5 + level / 2, x.size - 1) * x.std(ddof=1) / math.sqrt(x.size))
    return Interval(mean, mean - half, mean + half)


def tune_interval(values_by_tune: dict[int, list[float]], level: float = LEVEL) -> Interval:
    """A two-stage sample's mean and interval: over the values as they are for one tune, else the mean of each tune's
    mean and the Student-t interval over those means (tunes with no value left out)."""
    filled = [values for values in values_by_tune.values() if values]
    if len(values_by_tune) <= 1:
        return mean_interval([v for values in filled for v in values], level)
    return mean_interval([float(np.mean(values)) for values in filled], level)


def paired_difference(runs: Sequence[RunFigures], a: str, b: str, mission: str, group: str,
                      figure: str = "rms_position_m") -> Interval:
    """Mean and t-interval of `figure` of controller a minus b over the runs both completed on the same scenario and
    seed (the seeds are shared, so this separates controllers that per-controller intervals cannot); `group`
    ALL_GROUPS pairs every group. With several tunes, tune i of a is paired with tune i of b (independent draws
    both) and the interval is over the tunes' mean differences (`tune_interval`)."""
    def by_run(kind: str) -> dict[tuple[int, str, int], float]:
        return {(r.tune, r.scenario, r.seed): getattr(r, figure) for r in runs
                if r.controller == kind and r.mission == mission and r.completed
                and group in (ALL_GROUPS, r.group)}
    first, second = by_run(a), by_run(b)
    tunes = {r.tune for r in runs if r.mission == mission and r.controller in (a, b)}
    differences: dict[int, list[float]] = {tune: [] for tune in tunes}
    for key in first.keys() & second.keys():
        differences[key[0]].append(first[key] - second[key])
    return tune_interval(differences)


def max_thrust(mission: Mission, scenario: Scenario) -> float:
    """N per thruster in a scenario: its own limit, else the mission's, else the tuner's default."""
    return scenario.max_thrust or mission.limits.max_thrust or tuning.DEFAULT_MAX_THRUST


def electrical_power(model: Vehicle, wrench: np.ndarray, thrust_limit: float) -> np.ndarray:
    """W drawn by the thrusters giving `wrench` (N, 6): pseudo-inverse allocation, each thrust within
    +-thrust_limit, its current from the T200 data at VOLTAGE; (N,)."""
    B = allocation_matrix(model.thruster_positions, model.thruster_directions)
    thrusts = np.clip(wrench @ np.linalg.pinv(B).T, -thrust_limit, thrust_limit)
    t200 = thruster_curve(model)
    return VOLTAGE * t200.current(t200.pwm(thrusts, VOLTAGE), VOLTAGE).sum(axis=1)


def run_figures(trace: Trace, model: Vehicle, capacity: np.ndarray, thrust_limit: float) -> dict:
    """A run's FIGURES (and `completed`) from its trace; `capacity` (6,) is the wrench the plant was clipped to."""
    dt = float(trace.t[1] - trace.t[0]) if trace.t.size > 1 else 0.0
    pos, att = tracking_errors(trace.eta, trace.reference[:, :6])
    commanded = trace.tau[:-1]            # the last tick's command is never applied
    applied = np.clip(commanded, -capacity, capacity)
    energy = float(electrical_power(model, applied, thrust_limit).sum() * dt) / 3600.0
    saturated = np.any(np.abs(commanded) > capacity, axis=1)
    return {"completed": bool(trace.completed),
            "rms_position_m": float(np.sqrt(np.mean(pos**2))),
            "max_position_m": float(pos.max()),
            "rms_attitude_rad": float(np.sqrt(np.mean(att**2))),
            "energy_wh": energy,
            "saturation_fraction": float(saturated.mean()) if saturated.size else 0.0}


def replay(mission: Mission, settings: ControllerSettings, model: Vehicle, scenario: Scenario, seed: int,
           navigation_errors: NavigationErrors | None = None) -> tuple[Trace, np.ndarray]:
    """A held-out run as the bench flies it, recorded: `simulate` with the scenario's plant, water and noise seed
    (and the mission's navigation), the wrench clipped to the thrusters' capacity. Returns the trace and that
    capacity (6,)."""
    capacity = tuning.wrench_capacity(model, max_thrust(mission, scenario))
    trace = simulate(mission, settings, model, plant=model.scaled(scenario.plant_scale),
                     environment=scenario.environment, seed=seed, wrench_limit=capacity,
                     navigation_errors=navigation_errors)
    return trace, capacity


def evaluate(mission: Mission, settings: ControllerSettings, model: Vehicle, scenario: Scenario, seed: int,
             tune: int = FIRST_SWARM_SEED, navigation_errors: NavigationErrors | None = None) -> RunFigures:
    """One held-out run's figures."""
    trace, capacity = replay(mission, settings, model, scenario, seed, navigation_errors)
    figures = run_figures(trace, model, capacity, max_thrust(mission, scenario))
    return RunFigures(settings.kind, mission.name, scenario.name, scenario.group, seed, **figures, tune=tune)


def tune_controller(mission: Mission, kind: str, model: Vehicle, training: Sequence[Scenario],
                    options: pso.PSOOptions, backend: tuning.Backend,
                    callback: Callable[[int, float], None] | None = None,
                    swarm_seed: int = FIRST_SWARM_SEED,
                    navigation_errors: NavigationErrors | None = None) -> Tuned:
    """PSO of `kind`'s tuned gains on the mission over the training scenarios (the bench's common rules)."""
    start = load_settings(kind)
    problem = tuning.build_problem(mission, start, model, training, navigation_errors=navigation_errors)
    lower, upper = start.family.default_bounds()
    t0 = time.perf_counter()
    result = tuning.tune(problem, lower, upper, options, swarm_seed, backend, callback)
    return Tuned(mission.name, start.with_gains(result.best_position), result.best_cost, time.perf_counter() - t0,
                 swarm_seed)


def swarm_seeds(tunes: int) -> range:
    """The swarm seeds of `tunes` independent tunes."""
    return range(FIRST_SWARM_SEED, FIRST_SWARM_SEED + tunes)


def held_out_runs(held_out: Sequence[Scenario], seeds: int) -> list[tuple[Scenario, int]]:
    """Every (scenario, noise seed) the bench flies: seeds scenario.seed .. scenario.seed + seeds - 1."""
    return [(scenario, scenario.seed + j) for scenario in held_out for j in range(seeds)]


def summarize(runs: Sequence[RunFigures]) -> list[Summary]:
    """Per controller x mission x group, then x all groups, in the order the runs came; each figure over the
    completed runs (`tune_interval`: by tune when there are several)."""
    keys: dict[tuple[str, str, str], list[RunFigures]] = {}
    for run in runs:
        keys.setdefault((run.controller, run.mission, run.group), []).append(run)
        keys.setdefault((run.controller, run.mission, ALL_GROUPS), []).append(run)
    out = []
    for (controller, mission, group), members in keys.items():
        done: dict[int, list[RunFigures]] = {r.tune: [] for r in members}
        for r in members:
            if r.completed:
                done[r.tune].append(r)
        figures = {f: tune_interval({tune: [getattr(r, f) for r in runs] for tune, runs in done.items()})
                   for f in FIGURES}
        failures = len(members) - sum(map(len, done.values()))
        out.append(Summary(controller, mission, group, len(members), failures, figures))
    return out


@dataclass(frozen=True)
class BenchResult:
    tuned: list[Tuned]
    runs: list[RunFigures]
    summaries: list[Summary]
    timing: dict[str, float]


def _ticks(mission: Mission) -> int:
    return mission.sampled_reference(CONTROL_DT).shape[0]


def work(missions: Sequence[Mission], controllers: Sequence[str], training: dict[str, list[Scenario]],
         held_out: dict[str, list[Scenario]], seeds: int, options: pso.PSOOptions, tunes: int = 1) -> int:
    """Simulated ticks the bench will run (PSO iterations x particles x training scenarios, plus the held-out runs,
    per tune): the unit of its progress."""
    return sum(tunes * len(controllers) * _ticks(m)
               * (options.iterations * options.particles * len(training[m.name]) + seeds * len(held_out[m.name]))
               for m in missions)


def run_bench(missions: Sequence[Mission], controllers: Sequence[str], model: Vehicle,
              training: dict[str, list[Scenario]], held_out: dict[str, list[Scenario]], seeds: int,
              options: pso.PSOOptions, backend: tuning.Backend, threads: int,
              progress: Callable[[int], None] = lambda n: None, tunes: int = 1,
              navigation_errors: NavigationErrors | None = None) -> BenchResult:
    """The whole bench; training and held-out scenarios per mission name; `tunes` independent tunes per controller
    and mission. `progress(n)` after every PSO iteration and every held-out run with the ticks they simulated
    (`work` in all). `navigation_errors`: each mission's `environment: navigation` in every run."""
    t0 = time.perf_counter()
    tuned = []
    for m in missions:
        iteration = _ticks(m) * options.particles * len(training[m.name])
        tuned += [tune_controller(m, kind, model, training[m.name], options, backend,
                                  lambda it, best, n=iteration: progress(n), swarm_seed, navigation_errors)
                  for kind in controllers for swarm_seed in swarm_seeds(tunes)]
    t1 = time.perf_counter()
    by_name = {m.name: m for m in missions}
    jobs = [(by_name[t.mission], t, scenario, seed)
            for t in tuned for scenario, seed in held_out_runs(held_out[t.mission], seeds)]

    def job(args) -> RunFigures:
        mission, tune, scenario, seed = args
        figures = evaluate(mission, tune.settings, model, scenario, seed, tune.swarm_seed, navigation_errors)
        progress(_ticks(mission))
        return figures

    with ThreadPoolExecutor(threads) as pool:
        runs = list(pool.map(job, jobs))
    t2 = time.perf_counter()
    return BenchResult(tuned, runs, summarize(runs),
                       {"tune_s": t1 - t0, "evaluate_s": t2 - t1, "total_s": t2 - t0})


def result_document(result: BenchResult, settings: dict) -> dict:
    """Everything measured, as plain JSON: the settings, timing, tuned gains, every run and every summary."""
    return {
        "settings": settings,
        "timing": result.timing,
        "tuned": [{"mission": t.mission, "controller": t.settings.kind, "swarm_seed": t.swarm_seed,
                   "training_cost": t.training_cost, "tune_s": t.elapsed_s, "gains": t.settings.as_yaml()}
                  for t in result.tuned],
        "runs": [asdict(r) for r in result.runs],
        "summary": [{"controller": s.controller, "mission": s.mission, "group": s.group, "runs": s.runs,
                     "failures": s.failures, **{f: asdict(i) for f, i in s.figures.items()}}
                    for s in result.summaries],
    }


def representative(runs: Sequence[RunFigures], controller: str, mission: str) -> RunFigures | None:
    """The controller's completed run on the mission whose RMS position error is the median of them (the lower
    middle one for an even count), or None when all diverged."""
    done = sorted((r for r in runs if r.controller == controller and r.mission == mission and r.completed),
                  key=lambda r: r.rms_position_m)
    return done[(len(done) - 1) // 2] if done else None
