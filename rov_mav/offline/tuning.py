"""What the tuner minimises: the cost of a gain set (Eq. 2.32, printed or tracking form) over scenarios.

A `TuningProblem` holds everything fixed during a tune. `costs` runs every (scenario, particle) pair through the
compiled closed loop (`loop_kernel.simulate_batch`) in chunks on a backend (threads here, Dask in `rov_mav.offline.cluster`);
each run is independent and seeded, so the result does not depend on the chunking or the backend.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import numpy as np
from pydantic import create_model
from scipy.optimize import linprog

from rov_mav import config
from rov_mav.control import law
from rov_mav.control.controller import ControllerSettings, Family, PositiveVec6
from rov_mav.mission.missions import Mission
from rov_mav.model import dynamics
from rov_mav.model.thrusters import allocation_matrix
from rov_mav.model.vehicle import Vehicle
from rov_mav.offline import loop_kernel, pso
from rov_mav.offline.scenarios import Scenario
from rov_mav.offline.simulation import NavigationErrors, Trace, navigation_errors_of

COSTS = ("tracking", "report")
AGGREGATES = ("mean", "worst")
DEFAULT_MAX_THRUST = 40.0   # N per thruster: the T200's reverse limit at 16 V, as in the missions' limits
NO_LIMIT = np.full(6, np.inf)   # the tuner's runs fail on saturation (tau_max) before any clipping could act
CHUNKS_PER_WORKER = 4       # tasks per worker thread and iteration: balances runs that stop early

# Tracking cost (ERRATA, PSO gap), Bryson's rule: each term divided by the square of its acceptable size, so 1 cm
# of position error, 1 degree of attitude error, and a corrective wrench equal to the axis capacity cost the same.
# The sliding variable is not weighted: s = e_dot + k1 e is scaled by the very gain being tuned.
TRACKING_ERROR_SCALE = np.array([0.01, 0.01, 0.01, np.radians(1.0), np.radians(1.0), np.radians(1.0)])

Batch = tuple[np.ndarray, np.ndarray]   # gains (n, G), scenario index (n,)


class Backend(Protocol):
    """Where batches of runs are evaluated: `map_runs` returns problem.run(*batch) for each batch, in order."""

    workers: int   # threads that run batches at once

    def map_runs(self, problem: "TuningProblem", batches: Sequence[Batch]) -> list: ...


def feedforward(model: Vehicle, ref: np.ndarray) -> np.ndarray:
    """tau_ff: the law's wrench on the reference itself (e = e_dot = 0, tau_hat = 0, Eq. 2.17), (N+1, 6)."""
    eta = ref[:, :6]
    nu = dynamics.body_velocity(eta, ref[:, 6:12])
    tau, _ = law.control_law(model, np.ones(6), np.ones(6), eta, nu, ref, np.zeros(6))
    return tau


def wrench_capacity(model: Vehicle, max_thrust: float) -> np.ndarray:
    """Largest |tau_i| each axis alone can get from the thrusters within +-max_thrust (linear programme), (6,)."""
    B = allocation_matrix(model.thruster_positions, model.thruster_directions)
    n = B.shape[1]
    capacity = np.empty(6)
    for i in range(6):
        # variables [f (n), t]: maximise t subject to B f = t e_i, |f_j| <= max_thrust
        unit = np.zeros((6, 1))
        unit[i] = 1.0
        res = linprog(np.r_[np.zeros(n), -1.0], A_eq=np.hstack([B, -unit]), b_eq=np.zeros(6),
                      bounds=[(-max_thrust, max_thrust)] * n + [(0, None)])
        capacity[i] = res.x[-1]
    return capacity


def cost_weights(kind: str, capacity: np.ndarray) -> np.ndarray:
    """Diagonals of [Q (on s); Q_e (on e); R (on tau - tau_ff)], (3, 6), for `report` or `tracking`."""
    if kind == "report":
        return np.array([np.ones(6), np.zeros(6), np.ones(6)])     # Sec. IV.i: Q = R = I
    if kind == "tracking":
        return np.array([np.zeros(6), TRACKING_ERROR_SCALE**-2.0, capacity**-2.0])
    raise ValueError(f"unknown cost '{kind}' (choose from {', '.join(COSTS)})")


@dataclass(frozen=True)
class TuningProblem:
    """A mission, a controller (all but its gains), a cost and the scenarios it is scored over."""

    model: np.ndarray        # (92,) the controller's vehicle, packed
    plants: np.ndarray       # (S, 92) each scenario's true vehicle
    envs: np.ndarray         # (S, 20) each scenario's water
    seeds: np.ndarray        # (S,) sensor-noise seeds
    nav_errors: np.ndarray   # (E, M, 6) the navigation's errors (M = 0: none), scenario i's nav_errors[nav_index[i]]
    nav_index: np.ndarray    # (S,)
    controller: tuple        # ControllerSettings.kernel_arguments()
    params: np.ndarray       # (P,) the controller's parameter vector; its first G entries are the tuned gains
    ref: np.ndarray          # (N+1, 18)
    dt: float
    x0: np.ndarray           # (12,)
    weights: np.ndarray      # (3, 6) see cost_weights
    tau_ff: np.ndarray       # (N+1, 6) zero for the printed cost
    tau_max: np.ndarray      # (6,) saturation limit
    aggregate: str           # mean | worst over scenarios

    @property
    def n_scenarios(self) -> int:
        return self.plants.shape[0]

    def run(self, gains: np.ndarray, scenario: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Cost and ticks completed of each (gains[j], scenario[j]) closed-loop run, (n,) each; one compiled call
        that releases the GIL."""
        n = gains.shape[0]
        cost, steps = np.zeros(n), np.zeros(n, dtype=np.int64)
        empty = np.zeros((n, 0, 6))
        params = np.tile(self.params, (n, 1))
        params[:, :gains.shape[1]] = gains
        loop_kernel.simulate_batch(self.plants[scenario], self.envs[scenario], self.model, params, *self.controller,
                                   self.ref, self.dt, 1, self.x0, self.seeds[scenario], self.nav_errors,
                                   self.nav_index[scenario], self.weights, self.tau_ff,
                                   self.tau_max, NO_LIMIT, empty, empty, empty, empty, empty, empty, cost, steps)
        return cost, steps

    def trace_cost(self, trace: Trace) -> float:
        """This problem's cost (Eq. 2.32, weights and feed-forward as set) recomputed from a completed run's logs."""
        n = len(trace.t) - 1
        e = law.tracking_error(trace.eta[:n], trace.reference[:n, :6])
        u = trace.tau[:n] - self.tau_ff[:n]
        q, q_e, r = self.weights
        return float(np.sum(trace.s[:n] ** 2 @ q + e**2 @ q_e + u**2 @ r) * self.dt)

    def scenario_costs(self, gains: np.ndarray, backend: Backend) -> np.ndarray:
        """Cost of every gain set (P, G) in every scenario, (S, P), as about CHUNKS_PER_WORKER batches per
        backend worker."""
        p = gains.shape[0]
        all_gains = np.tile(gains, (self.n_scenarios, 1))
        scenario = np.repeat(np.arange(self.n_scenarios), p)
        parts = np.array_split(np.arange(len(all_gains)), min(len(all_gains), CHUNKS_PER_WORKER * backend.workers))
        runs = backend.map_runs(self, [(all_gains[i], scenario[i]) for i in parts])
        return np.concatenate([cost for cost, _ in runs]).reshape(self.n_scenarios, p)

    def costs(self, gains: np.ndarray, backend: Backend) -> np.ndarray:
        """The objective: each gain set's scenario costs reduced by `aggregate`, (P,)."""
        per_scenario = self.scenario_costs(gains, backend)
        return per_scenario.mean(axis=0) if self.aggregate == "mean" else per_scenario.max(axis=0)


def build_problem(mission: Mission, settings: ControllerSettings, model: Vehicle, scenarios: Sequence[Scenario],
                  cost: str = "tracking", aggregate: str = "mean", duration: float | None = None,
                  dt: float = 0.01, navigation_errors: NavigationErrors | None = None) -> TuningProblem:
    """The tuning problem of a mission; the saturation limit is the thrusters' capacity per axis with the
    mission's `limits.max_thrust` (default DEFAULT_MAX_THRUST) per thruster. With `navigation_errors`, every
    scenario measures the state with the mission's navigation (`environment: navigation`), seeded by its seed."""
    if aggregate not in AGGREGATES:
        raise ValueError(f"unknown aggregate '{aggregate}' (choose from {', '.join(AGGREGATES)})")
    mission.check_offline()
    ref = mission.sampled_reference(dt, duration)
    capacity = wrench_capacity(model, mission.limits.max_thrust or DEFAULT_MAX_THRUST)
    seeds = np.array([s.seed for s in scenarios], dtype=np.int64)
    nav_errors, nav_index = navigation_errors_of(mission.environment.navigation, navigation_errors, seeds, ref, dt)
    return TuningProblem(
        model=model.packed(),
        plants=np.array([model.scaled(s.plant_scale).packed() for s in scenarios]),
        envs=np.array([s.environment.packed(model.scaled(s.plant_scale)) for s in scenarios]),
        seeds=seeds,
        nav_errors=nav_errors,
        nav_index=nav_index,
        controller=settings.kernel_arguments(),
        params=settings.vector,
        ref=ref,
        dt=dt,
        x0=np.concatenate([mission.start_pose, np.zeros(6)]),
        weights=cost_weights(cost, capacity),
        tau_ff=feedforward(model, ref) if cost == "tracking" else np.zeros((ref.shape[0], 6)),
        tau_max=capacity,
        aggregate=aggregate,
    )


def tune(problem: TuningProblem, lower: np.ndarray, upper: np.ndarray, options: pso.PSOOptions, seed: int,
         backend: Backend, callback: Callable[[int, float], bool | None] | None = None) -> pso.PSOResult:
    """PSO of the controller's tuned gains (e.g. [k1 | k2]) in the box [lower, upper] on `problem` (Eq. 2.33),
    evaluated on `backend`."""
    return pso.minimize(lambda gains: problem.costs(gains, backend), lower, upper, options, seed, callback)


class ThreadBackend:
    """The in-process `Backend`: batches run in `threads` threads (the kernel releases the GIL)."""

    def __init__(self, threads: int = 2):
        self.workers = threads
        self._pool = ThreadPoolExecutor(threads)

    def map_runs(self, problem: TuningProblem, batches: Sequence[Batch]) -> list:
        return list(self._pool.map(lambda batch: problem.run(*batch), batches))

    def close(self) -> None:
        self._pool.shutdown()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def load_bounds(path: str | Path, family: Family) -> tuple[np.ndarray, np.ndarray]:
    """Per-gain search box from YAML `lower: {GROUP: [6 values]...}`, `upper: {...}` naming each of the family's
    tuned groups (e.g. k1, k2 for the backstepping law, Eq. 2.33)."""
    box = create_model(f"_{family.name}_box", __base__=config.StrictModel,
                       **{g: (PositiveVec6, ...) for g in family.tuned})
    bounds_file = create_model(f"_{family.name}_bounds", __base__=config.StrictModel, lower=(box, ...),
                               upper=(box, ...))
    spec = config.load(bounds_file, path)
    lower = np.concatenate([getattr(spec.lower, g) for g in family.tuned])
    upper = np.concatenate([getattr(spec.upper, g) for g in family.tuned])
    if np.any(upper <= lower):
        i = int(np.flatnonzero(upper <= lower)[0])
        group = family.tuned[i // 6]
        raise config.ConfigError(f"{path}: upper.{group}[{i % 6}]: not above the lower bound {lower[i]:g}")
    return lower, upper
