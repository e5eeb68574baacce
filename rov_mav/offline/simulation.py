"""Offline closed-loop simulation: mission reference -> controller -> plant, no I/O (the compiled kernel)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from rov_mav.control.controller import ControllerSettings
from rov_mav.mission.missions import Mission
from rov_mav.model.environment import Environment
from rov_mav.model.navigation import Navigation
from rov_mav.model.vehicle import Vehicle
from rov_mav.offline import loop_kernel

CONTROL_DT = 0.01     # s: the report's 100 Hz control rate
SUBSTEPS = 1          # RK4 steps per control tick (see docs/explanation/model-and-law.md: one RK4 step of 10 ms is converged to < 1e-6 m)
NO_NAVIGATION = np.zeros((1, 0, 6))   # simulate_batch's navigation errors when the state is measured without any
# (navigation, seed, reference (N+1, 18), dt) -> (N+1, 6): a navigation's errors along a mission, position and body
# velocity (`sim_bridge.navigation.estimate_errors`, given by the commands: the offline layer does not import the bridge)
NavigationErrors = Callable[[Navigation, int, np.ndarray, float], np.ndarray]


def navigation_errors_of(navigation: Navigation | None, errors: NavigationErrors | None, seeds, ref: np.ndarray,
                         dt: float) -> tuple[np.ndarray, np.ndarray]:
    """simulate_batch's (nav_errors (E, M, 6), nav_index (len(seeds),)): one error sequence per distinct seed, or
    none (M = 0) for no navigation, the ideal one, or no generator."""
    seeds = [int(s) for s in seeds]
    if navigation is None or navigation.ideal or errors is None:
        return NO_NAVIGATION, np.zeros(len(seeds), dtype=np.int64)
    distinct = sorted(set(seeds))
    table = np.array([errors(navigation, seed, ref, dt) for seed in distinct])
    return table, np.array([distinct.index(seed) for seed in seeds], dtype=np.int64)


@dataclass(frozen=True)
class Trace:
    """A run's time series, all sampled at the control ticks t_k = k dt."""

    t: np.ndarray           # (N,)
    eta: np.ndarray         # (N, 6) true pose
    nu: np.ndarray          # (N, 6) true body velocity
    reference: np.ndarray   # (N, 18) eta_d, eta_dot_d, eta_ddot_d
    tau: np.ndarray         # (N, 6) commanded wrench
    tau_hat: np.ndarray     # (N, 6) the wrench the law holds against the disturbance (the estimate)
    s: np.ndarray           # (N, 6) sliding variable (zeros for pid)
    gamma: np.ndarray       # (N, 6) adaptation rates (constant and fuzzy only)
    true_disturbance: np.ndarray | None   # (6,) when constant
    completed: bool         # ran to the end without diverging


def simulate(mission: Mission, settings: ControllerSettings, model: Vehicle, plant: Vehicle | None = None,
             environment: Environment | None = None, duration: float | None = None, dt: float = CONTROL_DT,
             substeps: int = SUBSTEPS, seed: int = 0, wrench_limit: np.ndarray | None = None,
             navigation_errors: NavigationErrors | None = None) -> Trace:
    """One closed-loop run, recorded. `model` is the controller's vehicle, `plant` the simulated one (default same);
    `wrench_limit` (6,): the plant receives the commanded wrench clipped to it per axis (default: unclipped);
    `navigation_errors`: the law measures the state with the navigation's errors (the environment's, else the
    mission's; seeded by `seed`)."""
    mission.check_offline()
    environment = mission.environment if environment is None else environment
    plant = model if plant is None else plant
    ref = mission.sampled_reference(dt, duration)
    n = ref.shape[0]
    logs = [np.zeros((1, n, 6)) for _ in range(6)]
    cost = np.zeros(1)
    steps = np.zeros(1, dtype=np.int64)
    x0 = np.concatenate([mission.start_pose, np.zeros(6)])
    weights, tau_ff, tau_max, tau_limit = loop_kernel.printed_cost(ref)
    if wrench_limit is not None:
        tau_limit = np.asarray(wrench_limit, float)
    navigation = environment.navigation if environment.navigation is not None else mission.environment.navigation
    nav_errors, nav_index = navigation_errors_of(navigation, navigation_errors, [seed], ref, dt)
    loop_kernel.simulate_batch(plant.packed()[None], environment.packed(plant)[None], model.packed(), settings.vector[None],
                               *settings.kernel_arguments(), ref, dt, substeps, x0, np.array([seed], dtype=np.int64),
                               nav_errors, nav_index, weights, tau_ff, tau_max, tau_limit, *logs, cost, steps)
    done = int(steps[0])
    eta, nu, tau, tau_hat, s, gamma = (log[0, :done + 1] for log in logs)
    return Trace(t=np.arange(done + 1) * dt, eta=eta, nu=nu, reference=ref[:done + 1], tau=tau, tau_hat=tau_hat,
                 s=s, gamma=gamma, true_disturbance=environment.constant_disturbance,
                 completed=done == n - 1 and cost[0] < loop_kernel.DIVERGED_COST)
