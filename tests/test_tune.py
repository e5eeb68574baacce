"""Gain tuning: costs, saturation, scenarios, batched and distributed evaluation, and the `tune` command."""

from __future__ import annotations

import dataclasses
import json
import sys

import numpy as np
import pyarrow as pa
import pytest
from conftest import MISSIONS
from rerun.chunk import RrdReader

from rov_mav import cli, config
from rov_mav.control import backstepping
from rov_mav.control.controller import BACKSTEPPING, load_settings
from rov_mav.mission.missions import load_mission
from rov_mav.model import kernel
from rov_mav.offline import loop_kernel, pso, tuning
from rov_mav.offline.scenarios import load_scenarios, nominal
from rov_mav.offline.simulation import simulate

SHORT = 8.0   # s of the line per run: enough for the start transient and the adaptation to show


@pytest.fixture(scope="module")
def line():
    return load_mission(MISSIONS / "line.yaml")


@pytest.fixture(scope="module")
def fuzzy():
    return load_settings("fuzzy")


class Serial:
    """A backend without threads: the reference the others are held to."""

    def __init__(self, workers: int = 1):
        self.workers = workers   # only sets how many batches a swarm is split into

    def map_runs(self, problem, batches):
        return [problem.run(*batch) for batch in batches]


def test_feedforward_on_the_line_is_the_drag_at_the_line_speed(vehicle, line):
    """Eq. 3.1 at constant velocity and heading: the law's wrench on the reference is D(u) u in surge, zero in sway."""
    ref = line.sampled_reference(0.01, 5.0)
    tau_ff = tuning.feedforward(vehicle, ref)
    u = np.hypot(0.2, 0.2)
    drag = (vehicle.linear_damping[0] + vehicle.quadratic_damping[0] * u) * u
    np.testing.assert_allclose(tau_ff[:, 0], drag, rtol=1e-9)
    np.testing.assert_allclose(tau_ff[:, 1], 0.0, atol=1e-9)


def test_feedforward_is_what_the_compiled_law_commands_on_the_reference(vehicle, line, fuzzy):
    ref = line.sampled_reference(0.01, 12.0)[::150]
    tau_ff = tuning.feedforward(vehicle, ref)
    for k in range(len(ref)):
        R = np.array(kernel.rotation(1.0, 0.0, 1.0, 0.0, np.cos(ref[k, 5]), np.sin(ref[k, 5]))).reshape(3, 3)
        nu = np.concatenate([R.T @ ref[k, 6:9], ref[k, 9:12]])        # roll = pitch = 0 on the line
        tau, s, grad = np.zeros(6), np.zeros(6), np.zeros(6)
        eta = ref[k, :6].copy()
        backstepping.control_law(vehicle.packed(), fuzzy.k1, fuzzy.k2, eta, kernel.attitude_trig(eta), nu, ref[k],
                                 np.zeros(6), tau, s, grad)
        np.testing.assert_allclose(s, 0.0, atol=1e-12)
        np.testing.assert_allclose(tau, tau_ff[k], rtol=1e-9, atol=1e-9)


def test_wrench_capacity_of_the_heavy_frame(vehicle):
    """Four vectored thrusters at 45 degrees give 4 cos(45) f_max in surge and sway; four vertical ones 4 f_max."""
    cap = tuning.wrench_capacity(vehicle, 40.0)
    np.testing.assert_allclose(cap[:2], 4 * 40.0 * np.cos(np.pi / 4), rtol=1e-3)
    np.testing.assert_allclose(cap[2], 160.0, rtol=5e-3)     # slightly less: the frame is not exactly symmetric
    assert np.all(cap[3:] > 1.0) and np.all(cap[3:] < 60.0)
    np.testing.assert_allclose(tuning.wrench_capacity(vehicle, 20.0), cap / 2, rtol=1e-6)


def test_report_cost_is_eq_2_32_with_identity_weights(vehicle, line, fuzzy):
    problem = tuning.build_problem(line, fuzzy, vehicle, [nominal(line.environment)], cost="report",
                                   duration=SHORT)
    trace = simulate(line, fuzzy, vehicle, duration=SHORT)
    n = len(trace.t) - 1
    expected = np.sum(trace.s[:n] ** 2 + trace.tau[:n] ** 2) * 0.01
    cost = problem.run(fuzzy.gains[None], np.zeros(1, dtype=np.int64))[0][0]
    assert cost == pytest.approx(expected, rel=1e-9)
    assert problem.trace_cost(trace) == pytest.approx(expected, rel=1e-9)


def test_tracking_cost_sees_tracking_and_the_report_cost_barely_does(vehicle, line, fuzzy):
    """ERRATA: with Q = R = I the effort term swamps tracking. Stiff gains track ~4x better on the line: the
    tracking cost ranks them far ahead, the printed cost barely tells them apart."""
    soft, stiff = np.full(12, 1.0), np.full(12, 8.0)
    ratio = {}
    for cost in tuning.COSTS:
        problem = tuning.build_problem(line, fuzzy, vehicle, [nominal(line.environment)], cost=cost,
                                       duration=SHORT)
        c = problem.costs(np.stack([soft, stiff]), Serial())
        ratio[cost] = c[0] / c[1]
    assert ratio["tracking"] > 5.0
    assert abs(ratio["report"] - 1.0) < 0.1


def test_a_saturating_or_diverging_particle_gets_a_large_finite_cost(vehicle, line, fuzzy):
    problem = tuning.build_problem(line, fuzzy, vehicle, [nominal(line.environment)], duration=SHORT)
    gains = np.stack([fuzzy.gains, np.full(12, 60.0), np.full(12, 0.5)])   # fine, saturates at start, fine
    costs, steps = problem.run(gains, np.zeros(3, dtype=np.int64))
    assert costs[1] == loop_kernel.DIVERGED_COST and steps[1] == 0          # the first tick's wrench is out of reach
    assert np.all(np.isfinite(costs)) and costs[0] < 1e6 and costs[2] < 1e6
    assert steps[0] == steps[2] == problem.ref.shape[0] - 1
    coarse = line.sampled_reference(0.05, SHORT)      # 400 gains at 20 Hz: the discrete loop blows up
    unlimited = dataclasses.replace(problem, tau_max=np.full(6, np.inf), dt=0.05, ref=coarse,
                                    tau_ff=np.zeros((len(coarse), 6)))
    cost, steps = unlimited.run(np.full((1, 12), 400.0), np.zeros(1, dtype=np.int64))
    assert cost[0] == loop_kernel.DIVERGED_COST and 0 < steps[0] < SHORT / 0.05


def test_scenario_costs_equal_separate_single_scenario_problems(vehicle, line, fuzzy):
    scenarios = load_scenarios(MISSIONS / "scenarios" / "robust.yaml", line.environment)
    assert len(scenarios) >= 5 and {s.plant_scale for s in scenarios} >= {0.8, 1.0, 1.2}
    chosen = [scenarios[i] for i in (1, 3, 5)]     # heavier plant, current, sensor noise
    gains = fuzzy.gains * np.random.default_rng(1).uniform(0.5, 1.5, (4, 12))
    problem = tuning.build_problem(line, fuzzy, vehicle, chosen, duration=SHORT)
    together = problem.scenario_costs(gains, Serial(3))
    for i, scenario in enumerate(chosen):
        alone = tuning.build_problem(line, fuzzy, vehicle, [scenario], duration=SHORT)
        np.testing.assert_array_equal(alone.scenario_costs(gains, Serial())[0], together[i])
    assert len({tuple(row) for row in together}) == 3          # the scenarios do differ
    np.testing.assert_array_equal(problem.costs(gains, Serial(2)), together.mean(axis=0))
    worst = dataclasses.replace(problem, aggregate="worst")
    np.testing.assert_array_equal(worst.costs(gains, Serial(2)), together.max(axis=0))


def test_threads_give_the_serial_result(vehicle, line, fuzzy):
    problem = tuning.build_problem(line, fuzzy, vehicle, [nominal(line.environment)], duration=SHORT)
    gains = np.random.default_rng(2).uniform(0.1, 10.0, (9, 12))
    with tuning.ThreadBackend(2) as backend:
        threaded = problem.costs(gains, backend)
    np.testing.assert_array_equal(threaded, problem.costs(gains, Serial()))


def test_scenario_file_errors_name_the_file_and_key(tmp_path, line):
    bad = tmp_path / "bad.yaml"
    bad.write_text("scenarios:\n  - name: a\n    plant_scal: 1.2\n")
    with pytest.raises(config.ConfigError, match=r"bad.yaml: scenarios\[0\].plant_scal: unknown key"):
        load_scenarios(bad, line.environment)
    bad.write_text("scenarios:\n  - name: a\n  - name: a\n")
    with pytest.raises(config.ConfigError, match="duplicate name 'a'"):
        load_scenarios(bad, line.environment)


def test_bounds_file(tmp_path):
    path = tmp_path / "bounds.yaml"
    path.write_text("lower: {k1: [1, 1, 1, 1, 1, 1], k2: [0.5, 0.5, 0.5, 0.5, 0.5, 0.5]}\n"
                    "upper: {k1: [5, 5, 5, 5, 5, 5], k2: [9, 9, 9, 9, 9, 0.5]}\n")
    with pytest.raises(config.ConfigError, match=r"upper.k2\[5\]: not above the lower bound"):
        tuning.load_bounds(path, BACKSTEPPING)
    path.write_text(path.read_text().replace("9, 0.5]", "9, 2]"))
    lower, upper = tuning.load_bounds(path, BACKSTEPPING)
    assert lower.tolist() == [1.0] * 6 + [0.5] * 6 and upper.tolist() == [5.0] * 6 + [9.0] * 5 + [2.0]


def test_tuned_gains_beat_a_poor_starting_set(vehicle, line, fuzzy):
    problem = tuning.build_problem(line, fuzzy, vehicle, [nominal(line.environment)], duration=SHORT)
    poor = np.full(12, 0.3)
    with tuning.ThreadBackend(2) as backend:
        result = tuning.tune(problem, np.full(12, 0.1), np.full(12, 10.0), pso.PSOOptions(16, 12), 0, backend)
        poor_cost = problem.costs(poor[None], backend)[0]
    assert result.best_cost < 0.2 * poor_cost
    trace = simulate(line, fuzzy.with_gains(result.best_position), vehicle, duration=SHORT)
    assert problem.trace_cost(trace) == pytest.approx(result.best_cost, rel=1e-9)


@pytest.mark.process
def test_dask_local_cluster_gives_the_in_process_result(vehicle, line, fuzzy):
    from rov_mav.offline.cluster import DaskBackend

    scenarios = load_scenarios(MISSIONS / "scenarios" / "robust.yaml", line.environment)[:3]
    problem = tuning.build_problem(line, fuzzy, vehicle, scenarios, duration=2.0)
    box, options = (np.full(12, 0.1), np.full(12, 10.0)), pso.PSOOptions(6, 3)
    with tuning.ThreadBackend(2) as backend:
        here = tuning.tune(problem, *box, options, 11, backend)
    with DaskBackend("local:2") as backend:
        assert backend.workers == 2
        there = tuning.tune(problem, *box, options, 11, backend)
    np.testing.assert_array_equal(there.position_history, here.position_history)
    np.testing.assert_array_equal(there.cost_history, here.cost_history)


def test_tune_command_writes_gains_that_simulate_accepts_and_reproduce_the_cost(tmp_path, capsys, vehicle, line):
    gains = tmp_path / "tuned" / "gains.yaml"
    assert cli.main(["tune", str(MISSIONS / "line.yaml"), "--particles", "8", "--iterations", "4", "--duration", "4",
                     "--bounds", "0.5,8", "--seed", "3", "--gains", "report", "--out", str(gains)]) == 0
    assert "best=" in capsys.readouterr().err                           # the progress bar shows the best cost
    comparison = json.loads((gains.parent / "comparison.json").read_text())
    assert (gains.parent / "convergence.png").stat().st_size > 10_000
    assert len(comparison["best_cost_per_iteration"]) == 4
    assert comparison["start"]["k1"] == [10.0, 1.0, 5.9, 1.7, 5.8, 0.8]         # Eq. 4.1
    settings = load_settings("fuzzy", gains)
    assert np.all((settings.gains >= 0.5) & (settings.gains <= 8.0))
    assert settings.k1.tolist() == comparison["tuned"]["k1"]
    # the tuner's reported cost, reproduced from a `simulate` run with the written file
    problem = tuning.build_problem(line, settings, vehicle, [nominal(line.environment)], duration=4.0)
    trace = simulate(line, settings, vehicle, duration=4.0)
    assert problem.trace_cost(trace) == pytest.approx(comparison["objective"]["tuned"], rel=1e-9)
    assert comparison["tuned"]["mission_cost"] == pytest.approx(comparison["objective"]["tuned"], rel=1e-9)
    metrics = tmp_path / "sim.json"
    assert cli.main(["simulate", str(MISSIONS / "line.yaml"), "--gains", str(gains), "--duration", "4",
                     "--out", str(tmp_path / "sim"), "--metrics", str(metrics)]) == 0
    simulated = json.loads(metrics.read_text())
    assert simulated["rms_position_error_m"] == pytest.approx(comparison["tuned"]["rms_position_error_m"], rel=1e-12)
    # the Rerun recording (no display in tests: saved beside the figure) holds the convergence per iteration
    chunks = RrdReader(gains.parent / "tune.rrd").stream().filter(content="/tuning/best_cost", is_static=False,
                                                                    components="Scalars:scalars").to_chunks()
    batch = pa.concat_tables([pa.Table.from_batches([c.to_record_batch()]) for c in chunks])
    order = np.argsort(batch.column("pso_iteration").to_numpy())
    logged = [v[0] for v in np.array(batch.column("Scalars:scalars").to_pylist(), dtype=object)[order]]
    np.testing.assert_allclose(logged, comparison["best_cost_per_iteration"], rtol=1e-12)


def test_tune_command_reports_a_bad_bounds_file_in_one_line(tmp_path, capsys):
    bounds = tmp_path / "b.yaml"
    bounds.write_text("lower: {k1: [1, 1, 1, 1, 1, 1]}\n")
    assert cli.main(["tune", str(MISSIONS / "line.yaml"), "--bounds-file", str(bounds)]) == 2
    assert capsys.readouterr().err.strip() == f"rov-mav tune: error: {bounds}: lower.k2: missing"


def test_a_tune_with_a_budget_stops_when_it_is_spent_and_keeps_the_best_so_far(tmp_path):
    gains = tmp_path / "gains.yaml"
    assert cli.main(["tune", str(MISSIONS / "line.yaml"), "--particles", "8", "--iterations", "10000", "--duration",
                     "4", "--budget", "1.5", "--out", str(gains), "--rerun", "off"]) == 0
    comparison = json.loads((tmp_path / "comparison.json").read_text())
    history = comparison["best_cost_per_iteration"]
    assert 1 <= len(history) < 10000 and comparison["elapsed_s"] < 10.0
    assert comparison["objective"]["tuned"] == pytest.approx(history[-1], rel=1e-9)


def test_a_cluster_without_dask_is_refused_in_one_line(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "dask.distributed", None)        # as on a machine without the cluster extra
    assert cli.main(["tune", str(MISSIONS / "line.yaml"), "--particles", "4", "--iterations", "1", "--duration", "2",
                     "--cluster", "local:1", "--out", str(tmp_path / "g.yaml"), "--rerun", "off"]) == 2
    assert capsys.readouterr().err.strip() == ("rov-mav tune: error: --cluster needs Dask, which is not installed: "
                                               "pip install 'rov-mav[cluster]'")
