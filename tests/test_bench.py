"""`rov-mav bench`: its statistics, the kernel's telemetry sampling and wrench clipping it relies on, the held-out set,
a tiny bench end to end through the CLI, and its one-line refusals."""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pyarrow as pa
import pytest
from conftest import MISSIONS
from rerun.chunk import RrdReader
from cli_helpers import assert_one_line, files_under, rov_mav
from bridge_helpers import ROV_MAV

from rov_mav import cli
from rov_mav.flight.state.prediction import StatePredictor
from rov_mav.control.controller import Controller, load_settings
from rov_mav.mission.metrics import trace_metrics
from rov_mav.mission.missions import load_mission
from rov_mav.model import kernel
from rov_mav.model.environment import Environment
from rov_mav.offline import bench, tuning
from rov_mav.offline.scenarios import load_scenarios
from rov_mav.offline.simulation import simulate

LINE = MISSIONS / "line.yaml"
TRAINING = MISSIONS / "scenarios" / "robust.yaml"
HELD_OUT = MISSIONS / "scenarios" / "bench.yaml"


@pytest.fixture(scope="module")
def line():
    return load_mission(LINE)


def test_t_interval_covers_a_known_mean_95_percent_of_the_time():
    """5 draws per sample: the t-interval covers the true mean in 95 % of 4000 samples (a normal-quantile interval
    would cover about 88 %), on skewed data too it stays near; 1..5 gives 3 +- t(0.975, 4) s / sqrt(5) = 1.963."""
    rng = np.random.default_rng(7)
    for draw, mean in ((lambda n: rng.normal(3.0, 2.0, n), 3.0), (lambda n: rng.gamma(8.0, 0.5, n), 4.0)):
        covered = 0
        for _ in range(4000):
            interval = bench.mean_interval(draw(5))
            covered += interval.low <= mean <= interval.high
        assert 0.93 <= covered / 4000 <= 0.965
    known = bench.mean_interval([1.0, 2.0, 3.0, 4.0, 5.0])
    assert (known.mean, known.low, known.high) == pytest.approx((3.0, 3.0 - 1.96324, 3.0 + 1.96324), abs=1e-5)


def test_paired_difference_separates_what_per_controller_intervals_cannot():
    """Two controllers on shared scenarios whose difficulty varies 10x more than the 1 cm between them: their own
    intervals overlap, the paired difference is exactly -1 cm, and it pairs only runs both completed."""
    rng = np.random.default_rng(3)
    hardness = rng.uniform(0.05, 0.25, 12)

    def run(kind, i, rms, completed=True):
        return bench.RunFigures(kind, "line", f"s{i // 3}", "g", i % 3, completed, rms, 0.0, 0.0, 0.0, 0.0)
    runs = [run("a", i, h) for i, h in enumerate(hardness)] + [run("b", i, h + 0.01) for i, h in enumerate(hardness)]
    runs.append(run("a", 12, 5.0, completed=False))
    runs.append(run("b", 12, 0.0))
    own = {s.controller: s.figures["rms_position_m"] for s in bench.summarize(runs) if s.group == "g"}
    assert own["a"].high > own["b"].low
    diff = bench.paired_difference(runs, "a", "b", "line", "g")
    assert diff.mean == pytest.approx(-0.01) and diff.high == pytest.approx(-0.01)


def test_with_several_tunes_the_unit_is_the_tune():
    """Four tunes whose gains landed apart (means 5, 10, 6, 12 cm) and whose runs barely vary within a tune: the
    figure is the mean of the tunes' means and its interval the t-interval over those four means, not the narrow
    one over 40 runs as if they were independent; a tune whose runs all diverged counts as failures only. Paired
    differences pair tune i with tune i and take their interval over the tunes."""
    rng = np.random.default_rng(5)
    means = {0: 0.05, 1: 0.10, 2: 0.06, 3: 0.12}

    def run(kind, tune, i, rms, completed=True):
        return bench.RunFigures(kind, "line", f"s{i // 2}", "g", i % 2, completed, rms, 0.0, 0.0, 0.0, 0.0, tune)
    runs = [run("a", t, i, m + rng.normal(0, 0.001)) for t, m in means.items() for i in range(10)]
    runs += [run("a", 4, i, 9.9, completed=False) for i in range(10)]
    summary = next(s for s in bench.summarize(runs) if s.group == "g")
    tune_means = [np.mean([r.rms_position_m for r in runs if r.tune == t]) for t in means]
    expected = bench.mean_interval(tune_means)
    got = summary.figures["rms_position_m"]
    assert (got.mean, got.low, got.high) == pytest.approx((expected.mean, expected.low, expected.high), rel=1e-12)
    assert (summary.runs, summary.failures) == (50, 10)
    pooled = bench.mean_interval([r.rms_position_m for r in runs if r.completed])
    assert got.high - got.low > 5 * (pooled.high - pooled.low)
    runs += [run("b", t, i, r.rms_position_m + 0.01 * (t + 1)) for t in means
             for i, r in enumerate(x for x in runs if x.tune == t)]
    diff = bench.paired_difference(runs, "b", "a", "line", "g")
    assert diff.mean == pytest.approx(0.025) and (diff.low, diff.high) == pytest.approx(
        (bench.mean_interval([0.01, 0.02, 0.03, 0.04]).low, bench.mean_interval([0.01, 0.02, 0.03, 0.04]).high))


def test_the_interval_over_tunes_covers_the_laws_mean_and_pooling_the_runs_does_not():
    """A two-stage sample as the bench draws it: each tune lands with an offset N(0, 1 cm) from the law's mean, its
    runs scatter N(0, 0.3 cm) around that. Over 2000 benches of 5 tunes x 8 runs, the interval over the tunes covers
    the law's mean 95 % of the time; the interval over the 40 runs pooled, far less often."""
    rng = np.random.default_rng(11)
    covered = pooled_covered = 0
    for _ in range(2000):
        offsets = rng.normal(0.0, 1.0, 5)
        values = {t: list(5.0 + offsets[t] + rng.normal(0.0, 0.3, 8)) for t in range(5)}
        interval = bench.tune_interval(values)
        pooled = bench.mean_interval([v for vs in values.values() for v in vs])
        covered += interval.low <= 5.0 <= interval.high
        pooled_covered += pooled.low <= 5.0 <= pooled.high
    assert 0.93 <= covered / 2000 <= 0.97
    assert pooled_covered / 2000 < 0.6


@pytest.mark.parametrize("predict", [False, True])
def test_the_controller_sees_sampled_delayed_telemetry(vehicle, line, predict):
    """10 Hz samples 0.15 s late: the runner's Controller fed, at each tick, the true state of the last sample that
    has arrived (tick 0's before any) -- carried forward to the tick by the runner's own StatePredictor, which learns
    from each new sample and is told each command, when the loop predicts -- reproduces the batched run's commands
    exactly; the delay changes the run."""
    settings = load_settings("fuzzy", "report")   # stateful: its estimate integrates what it was shown
    delayed = Environment(disturbance=line.environment.disturbance, telemetry=np.array([0.1, 0.15]), predict=predict)
    trace = simulate(line, settings, vehicle, environment=delayed, duration=6.0)
    assert trace.completed
    controller = Controller(vehicle, settings)
    predictor = StatePredictor(controller.model, 0.01)
    every, late, dt = 10, 15, 0.01
    for k in range(len(trace.t)):
        arrived = max(0, (k - late) // every * every) if k >= late else 0
        eta, nu = trace.eta[arrived], trace.nu[arrived]
        if predict:
            if k >= late and (k - late) % every == 0:
                predictor.observe(arrived * dt, eta, nu)
            eta, nu = predictor.predicted(arrived * dt, eta, nu, k * dt)
        out = controller.step(eta, nu, trace.reference[k], dt)
        np.testing.assert_allclose(out.tau, trace.tau[k], rtol=0, atol=1e-9, err_msg=f"tick {k}")
        predictor.commanded(k * dt, out.tau)
    prompt = simulate(line, settings, vehicle, environment=line.environment, duration=6.0)
    assert np.abs(prompt.eta - trace.eta).max() > 1e-3


def test_the_plant_receives_the_clipped_wrench(vehicle, line):
    """With a wrench limit the commands exceed it, and each logged step is one RK4 step of the plant under the
    clipped command; an infinite limit is the unclipped run bit for bit."""
    limit = np.array([15.0, 15.0, 15.0, 0.5, 0.5, 0.5])
    settings = load_settings("smc")
    trace = simulate(line, settings, vehicle, duration=3.0, wrench_limit=limit)
    assert np.any(np.abs(trace.tau) > limit)
    env, ws = line.environment.packed(), np.zeros(80)
    for k in range(len(trace.t) - 1):
        x = np.concatenate([trace.eta[k], trace.nu[k]])
        kernel.rk4_step(vehicle.packed(), env, x, np.clip(trace.tau[k], -limit, limit), k * 0.01, 0.01, ws)
        np.testing.assert_allclose(x, np.concatenate([trace.eta[k + 1], trace.nu[k + 1]]), rtol=0, atol=1e-12)
    free = simulate(line, settings, vehicle, duration=3.0)
    unlimited = simulate(line, settings, vehicle, duration=3.0, wrench_limit=np.full(6, np.inf))
    assert np.array_equal(free.eta, unlimited.eta) and not np.array_equal(free.eta, trace.eta)


@pytest.mark.parametrize("training_file", [TRAINING, *(MISSIONS / "scenarios" / f"robust_{name}.yaml" for name in ("telemetry", "dive"))])
def test_held_out_scenarios_differ_from_training(line, training_file):
    """No held-out scenario repeats a training one (of either shipped training set); every held-out one has noise
    and sampled, delayed telemetry (robust.yaml has neither together); their seeds are disjoint; every condition the
    issue names is there."""
    training = load_scenarios(training_file, line.environment)
    held_out = load_scenarios(HELD_OUT, line.environment)

    def key(s):
        return s.plant_scale, s.max_thrust, tuple(s.environment.packed())
    assert not {key(s) for s in held_out} & {key(s) for s in training}
    if training_file == TRAINING:
        assert all(s.environment.telemetry[0] == s.environment.telemetry[1] == 0 for s in training)
    for s in held_out:
        assert 0.1 <= s.environment.telemetry[0] <= 0.2 and s.environment.telemetry[1] > 0   # 5-10 Hz, late
        assert np.all(s.environment.noise > 0)
    assert not {s.seed for s in training} & {s.seed + j for s in held_out for j in range(5)}
    assert {s.plant_scale for s in held_out} >= {0.8, 1.2}
    assert any(np.any(s.environment.current) for s in held_out)
    assert any(s.environment.disturbance_period > 0 for s in held_out)
    assert any(s.max_thrust is not None and s.max_thrust < 40 for s in held_out)


def test_tiny_bench_through_the_cli(tmp_path, capsys, vehicle, line):
    """2 controllers, the line, 2 seeds, a 4x2 swarm: every output is written, and its numbers are the runs'
    (each JSON run equals an independent simulate of the tuned gains written beside it; each summary, its runs)."""
    out = tmp_path / "bench"
    assert cli.main(["bench", "--controllers", "pid,smc", "--missions", str(LINE), "--seeds", "2",
                     "--tune-budget", "4x2", "--out", str(out)]) == 0
    printed = capsys.readouterr()
    assert "bench:" in printed.err                     # the progress bar
    doc = json.loads((out / "bench.json").read_text())
    held_out = {s.name: s for s in load_scenarios(HELD_OUT, line.environment)}
    assert len(doc["runs"]) == 2 * 2 * len(held_out)
    for kind in ("pid", "smc"):
        settings = load_settings(kind, out / "gains" / f"line-{kind}.yaml")
        assert [t["gains"] for t in doc["tuned"] if t["controller"] == kind] == [settings.as_yaml()]
        for run in [r for r in doc["runs"] if r["controller"] == kind][::5]:
            scenario = held_out[run["scenario"]]
            capacity = tuning.wrench_capacity(vehicle, scenario.max_thrust or 40.0)
            trace = simulate(line, settings, vehicle, plant=vehicle.scaled(scenario.plant_scale),
                             environment=scenario.environment, seed=run["seed"], wrench_limit=capacity)
            metrics = trace_metrics("line", kind, trace)
            assert run["completed"] == metrics["completed"]
            assert run["rms_position_m"] == pytest.approx(metrics["rms_position_error_m"], rel=1e-12)
            assert run["rms_attitude_rad"] == pytest.approx(metrics["rms_attitude_error_rad"], rel=1e-12)
            assert 0 < run["energy_wh"] < 300 and 0 <= run["saturation_fraction"] <= 1
    for row in doc["summary"]:
        members = [r for r in doc["runs"] if r["controller"] == row["controller"]
                   and (row["group"] == "all" or r["group"] == row["group"])]
        done = [r["rms_position_m"] for r in members if r["completed"]]
        assert row["runs"] == len(members) and row["failures"] == len(members) - len(done)
        if done:
            assert row["rms_position_m"]["mean"] == pytest.approx(np.mean(done), rel=1e-12)
            assert row["rms_position_m"]["low"] <= row["rms_position_m"]["mean"] <= row["rms_position_m"]["high"]
    table = (out / "bench.md").read_text()
    assert "| pid | all | 16 |" in table and "| smc | waves | 2 |" in table
    assert (out / "errors-line.png").stat().st_size > 10_000
    for kind in ("pid", "smc"):   # the recording holds the controller's median completed run
        done = sorted(r["rms_position_m"] for r in doc["runs"] if r["controller"] == kind and r["completed"])
        if not done:
            assert not (out / "rerun" / f"{kind}.rrd").exists()
            continue
        chunks = RrdReader(out / "rerun" / f"{kind}.rrd").stream().filter(
            content="/error/position", is_static=False, components="Scalars:scalars").to_chunks()
        table = pa.concat_tables([pa.Table.from_batches([c.to_record_batch()]) for c in chunks])
        norms = np.array([v[3] for v in table.column("Scalars:scalars").to_pylist()])
        assert np.sqrt(np.mean(norms**2)) == pytest.approx(done[(len(done) - 1) // 2], rel=1e-9)


def test_several_tunes_through_the_cli(tmp_path, capsys, line):
    """--tunes 2: two tunes per controller (swarm seeds 0 and 1), each flown on every held-out run; seed 0's tune is
    the one a single-tune bench makes; each summary is the mean of the tunes' means; bench.md shows each tune."""
    one, two = tmp_path / "one", tmp_path / "two"
    common = ["bench", "--controllers", "smc", "--missions", str(LINE), "--seeds", "1", "--tune-budget", "4x2"]
    assert cli.main([*common, "--out", str(one)]) == 0
    assert cli.main([*common, "--tunes", "2", "--out", str(two)]) == 0
    capsys.readouterr()
    single, double = json.loads((one / "bench.json").read_text()), json.loads((two / "bench.json").read_text())
    assert [t["swarm_seed"] for t in double["tuned"]] == [0, 1]
    assert double["tuned"][0]["gains"] == single["tuned"][0]["gains"] != double["tuned"][1]["gains"]
    for seed in (0, 1):
        written = load_settings("smc", two / "gains" / f"line-smc-seed{seed}.yaml")
        assert written.as_yaml() == double["tuned"][seed]["gains"]
    assert [r for r in double["runs"] if r["tune"] == 0] == single["runs"]
    assert len(double["runs"]) == 2 * len(single["runs"])
    for row in double["summary"]:
        per_tune = [[r["rms_position_m"] for r in double["runs"] if r["tune"] == t and r["completed"]
                     and row["group"] in ("all", r["group"])] for t in (0, 1)]
        if all(per_tune):
            assert row["rms_position_m"]["mean"] == pytest.approx(np.mean([np.mean(v) for v in per_tune]),
                                                                  rel=1e-12)
    table = (two / "bench.md").read_text()
    assert "2 independent tunes, swarm seeds 0-1" in table and "| line | smc | " in table.split("## Each tune")[1]


@pytest.mark.process
def test_into_a_log_the_progress_bar_writes_seldom(tmp_path):
    """stderr a pipe (a CI log, `2> file`): the bar starts and ends, and in between updates every 30 s at most,
    not every 0.1 s as on a terminal (a 6-minute bench wrote 1,000 updates into a log before)."""
    done = subprocess.run([ROV_MAV, "bench", "--controllers", "smc", "--missions", str(LINE), "--seeds", "1",
                           "--tune-budget", "4x3", "--out", str(tmp_path / "out")],
                          capture_output=True, text=True, timeout=300, stdin=subprocess.DEVNULL)
    assert done.returncode == 0, done.stderr
    updates = [u for u in done.stderr.replace("\r", "\n").splitlines() if u.startswith("bench:") and "tick" in u]
    assert 2 <= len(updates) <= 3 and "100%" in updates[-1], done.stderr


@pytest.mark.parametrize("argv,fragments", [
    (["--controllers", "pid,lqr"], ["argument --controllers: 'lqr': unknown controller"]),
    (["--missions", "nowhere.yaml"], ["nowhere.yaml", "no such file"]),
    (["--tune-budget", "30"], ["argument --tune-budget: 30: expected PARTICLESxITERATIONS"]),
    (["--tune-budget", "0x5"], ["argument --tune-budget: 0x5: particles from 1"]),
    (["--seeds", "0"], ["argument --seeds: 0"]),
    (["--tunes", "0"], ["argument --tunes: 0"]),
    (["--scenarios", "missing.yaml"], ["missing.yaml", "no such file"]),
    (["--scenarios", "{bad}"], ["plant_scale"]),
    (["--training", "{bad}"], ["plant_scale"]),
])
def test_bad_input_is_one_line_and_writes_nothing(tmp_path, capsys, argv, fragments):
    bad = tmp_path / "bad.yaml"
    bad.write_text("scenarios:\n  - name: x\n    plant_scale: 9\n")
    out = tmp_path / "out"
    status, err = rov_mav(["bench", *[a.replace("{bad}", str(bad)) for a in argv], "--missions", str(LINE),
                           "--out", str(out)] if "--missions" not in argv else
                          ["bench", *argv, "--out", str(out)], capsys)
    assert status == 2
    assert_one_line(err, "rov-mav bench: error: ", *fragments)
    assert not out.exists() or not files_under(out)
