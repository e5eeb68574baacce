"""The controller family through its one compiled interface: each closes the loop on the line, the runner's
tick-by-tick controller and the batched offline loop agree, and the PSO tunes each one."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from conftest import MISSIONS

from rov_mav import cli, config
from rov_mav.control import ismc
from rov_mav.control.controller import KINDS, Controller, load_settings
from rov_mav.mission.missions import load_mission
from rov_mav.offline import pso, tuning
from rov_mav.offline.scenarios import nominal
from rov_mav.offline.simulation import simulate

ALL = list(KINDS)
NEW = ["pid", "smc", "ismc"]


@pytest.fixture(scope="module")
def line():
    return load_mission(MISSIONS / "line.yaml")


@pytest.mark.parametrize("kind", ALL)
def test_each_controller_converges_on_the_line(vehicle, line, kind):
    """Against the line's constant disturbance (Eq. 3.2) from rest at the origin: the velocity-error transient
    (reference at 0.28 m/s from t = 0) is tracked out to centimetres, attitude to a fraction of a degree."""
    trace = simulate(line, load_settings(kind), vehicle)
    assert trace.completed
    error = np.linalg.norm(trace.eta[:, :3] - trace.reference[:, :3], axis=1)
    final = error[-500:]                                 # the last 5 s
    assert final.max() < 0.02, f"{kind}: {final.max():.4f} m"
    assert final.max() <= error[-1000:-500].max() + 1e-3  # settled: not growing
    attitude = np.abs(trace.eta[-500:, 3:] - trace.reference[-500:, 3:6])
    assert np.degrees(attitude.max()) < 2.0


@pytest.mark.parametrize("kind", NEW)
def test_integral_action_removes_the_steady_error(vehicle, line, kind):
    """pid and ismc integrate the error away under the constant disturbance (over 120 s: pid's shipped integrator,
    tuned for a delayed 50 Hz loop, is slow); smc keeps the boundary layer's error (|s| < phi), which the stronger
    disturbance of a doubled tau_d visibly grows."""
    settings = load_settings(kind)
    doubled = replace(line.environment, disturbance=2 * line.environment.disturbance)
    one, two = (np.linalg.norm(trace.eta[-1, :3] - trace.reference[-1, :3])
                for trace in (simulate(line, settings, vehicle, environment=env, duration=120.0)
                              for env in (line.environment, doubled)))
    if kind == "smc":
        assert two > 1.5 * one > 0.0
    else:
        assert two < 2e-3 and one < 2e-3


@pytest.mark.parametrize("kind", ALL)
def test_shipped_gains_hold_attitude_in_the_loop_run_flies(vehicle, line, kind):
    """The state at run's 50 Hz and 0.04 s old: no law chatters or oscillates in attitude (smc tuned without the
    delay switched its torques +-12-15 N m at 50 Hz: 0.25 rad RMS)."""
    run_loop = replace(line.environment, telemetry=np.array([0.02, 0.04]))
    trace = simulate(line, load_settings(kind), vehicle, environment=run_loop)
    attitude = np.sqrt(np.mean(np.sum((trace.eta[:, 3:] - trace.reference[:, 3:6]) ** 2, axis=1)))
    position = np.sqrt(np.mean(np.sum((trace.eta[:, :3] - trace.reference[:, :3]) ** 2, axis=1)))
    assert trace.completed and attitude < np.radians(2.0) and position < 0.03, (attitude, position)


@pytest.mark.parametrize("kind", ALL)
def test_tick_by_tick_and_batched_agree(vehicle, line, kind):
    """The runner's Controller.step replayed on a simulate_batch run's states gives that run's logged tau,
    tau_hat, s and gamma (one compiled law, one state update)."""
    settings = load_settings(kind)
    trace = simulate(line, settings, vehicle, duration=8.0)
    controller = Controller(vehicle, settings)
    for k in range(len(trace.t)):
        out = controller.step(trace.eta[k], trace.nu[k], trace.reference[k], 0.01)
        for name in ("tau", "tau_hat", "s", "gamma"):
            np.testing.assert_allclose(getattr(out, name), getattr(trace, name)[k], rtol=0, atol=1e-9,
                                       err_msg=f"{kind} {name} at tick {k}")
    assert np.abs(trace.tau_hat).max() > 0.1 or kind == "baseline"   # the compared state did evolve
    controller.reset()
    again = controller.step(trace.eta[0], trace.nu[0], trace.reference[0], 0.01)
    np.testing.assert_allclose(again.tau, trace.tau[0], rtol=0, atol=1e-9)


@pytest.mark.parametrize("kind", NEW)
def test_pso_tunes_each_controller(vehicle, line, kind):
    """From the family's default box, the swarm's best cost falls over the iterations and the best gains' run
    reproduces it."""
    settings = load_settings(kind)
    problem = tuning.build_problem(line, settings, vehicle, [nominal(line.environment)], duration=4.0)
    lower, upper = settings.family.default_bounds()
    assert lower.size == settings.gains.size
    with tuning.ThreadBackend(2) as backend:
        result = tuning.tune(problem, lower, upper, pso.PSOOptions(12, 8), 0, backend)
    assert result.cost_history[-1] < 0.9 * result.cost_history[0]
    trace = simulate(line, settings.with_gains(result.best_position), vehicle, duration=4.0)
    assert problem.trace_cost(trace) == pytest.approx(result.best_cost, rel=1e-9)


def test_tune_command_for_a_new_controller_writes_gains_simulate_accepts(tmp_path, capsys):
    gains = tmp_path / "smc.yaml"
    assert cli.main(["tune", str(MISSIONS / "line.yaml"), "--controller", "smc", "--particles", "6",
                     "--iterations", "3", "--duration", "3", "--out", str(gains), "--rerun", "off"]) == 0
    tuned = load_settings("smc", gains)
    shipped = load_settings("smc")
    assert set(tuned.params) == {"lam", "k", "phi"} and not np.array_equal(tuned.gains, shipped.gains)
    lower, upper = shipped.family.default_bounds()
    assert np.all((tuned.gains >= lower) & (tuned.gains <= upper))
    assert cli.main(["simulate", str(MISSIONS / "line.yaml"), "--controller", "smc", "--gains", str(gains),
                     "--duration", "3", "--out", str(tmp_path / "sim"), "--rerun", "off"]) == 0
    capsys.readouterr()


def test_ismc_tanh_is_the_library_tanh():
    """ismc's one-exp tanh, within 3e-16 of numpy's over its whole range (saturated tails, zero, both signs)."""
    for x in np.concatenate([np.linspace(-30.0, 30.0, 6001), [0.0, -0.0, 1e-300, -1e-12, 800.0, -800.0]]):
        assert abs(ismc.tanh(x) - np.tanh(x)) <= 3e-16


def test_the_report_law_ships_our_pso_gains_and_flies_the_reports_on_request():
    """Each kind of the report's law defaults to its own gains from our PSO (rov_mav/data/KIND.yaml, over the family's
    file); `--gains report` gives the report's Eqs. 4.1-4.2, which no other family has."""
    report = load_settings("fuzzy", "report")
    np.testing.assert_array_equal(report.k1, [10.0, 1.0, 5.9, 1.7, 5.8, 0.8])     # Eq. 4.1
    np.testing.assert_array_equal(report.k2, [5.2, 10.0, 1.0, 5.8, 1.9, 5.5])     # Eq. 4.2
    tuned = {kind: load_settings(kind) for kind in ("baseline", "constant", "fuzzy")}
    assert len({tuple(s.gains) for s in tuned.values()} | {tuple(report.gains)}) == 4
    for settings in tuned.values():
        np.testing.assert_array_equal(settings.constant_gamma, report.constant_gamma)   # from the family's file
        lower, upper = settings.family.default_bounds()
        assert np.all((settings.gains >= lower) & (settings.gains <= upper))
    with pytest.raises(config.ConfigError, match="--gains report: the report's gains"):
        load_settings("smc", "report")
