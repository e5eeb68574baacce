"""Benchmark: what Rerun logging and the state prediction cost the control loop, beside a 50 Hz loop's 20 ms period.

1. Rerun's own cost per tick for batches of 1..50 ticks (`send_ticks` into a file), the work the sink's thread does.
2. A 50 Hz loop paced like the runner's (sleep to the next 20 ms deadline, allocate tau to thrusts and PWMs, hand
   the record to the sinks), without and with the live sink: time inside `log_tick`, the sink thread's CPU time per
   tick, and how late the loop wakes up (does the logging thread delay it?).
3. A tick's computation from a state to its PWMs, as the runner does it (the law, the allocation, and with
   `--predict on` the disturbance learnt from the state and the state carried 0.12 s forward), with the prediction
   on and off in alternating rounds: p50 / p99 / max, the share of the telemetry-in to command-out budget (2 ms).
Run:
    .venv/bin/python tools/bench_telemetry.py [--seconds 10]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from rov_mav import telemetry
from rov_mav.control.controller import Controller, load_settings
from rov_mav.flight.thrusters.actuation import Actuation
from rov_mav.flight.state.prediction import StatePredictor
from rov_mav.flight.record.tick import TickRecord
from rov_mav.mission.missions import load_mission
from rov_mav.model.thrusters import Allocator, thrusts_to_pwms
from rov_mav.model.vehicle import load_vehicle
from rov_mav.offline.simulation import simulate
from rov_mav.telemetry.entities import TickColumns, log_static, send_ticks

ROOT = Path(__file__).resolve().parents[1]
PERIOD = 0.02   # s: 50 Hz
HORIZON = 0.12  # s: a state's age when its command acts through 50 ms of delay each way
BUDGET = 0.002  # s: telemetry in to command out, p99 (issue 18's target)


def records(n: int) -> list[TickRecord]:
    """n ticks of the square at 50 Hz, as the runner builds them."""
    mission, vehicle = load_mission(ROOT / "missions" / "square.yaml"), load_vehicle()
    trace = simulate(mission, load_settings("fuzzy"), vehicle, duration=n * PERIOD, dt=PERIOD)
    c = telemetry.trace_columns(trace, vehicle)
    return [TickRecord(t=c.t[k], vehicle_time=c.t[k], eta=c.eta[k], nu=trace.nu[k], reference=c.reference[k], tau=c.tau[k],
                       tau_hat=c.tau_hat[k], s=c.s[k], gamma=c.gamma[k], thrusts=c.thrusts[k], pwm=c.pwm[k],
                       progress=mission.progress(c.t[k]), telemetry_age=0.005, latency=0.001, control_rate=50.0,
                       battery_voltage=16.0, true_disturbance=trace.true_disturbance) for k in range(n)]


def batch_costs(ticks: list[TickRecord], folder: Path) -> None:
    vehicle = load_vehicle()
    print("| ticks per batch | Rerun CPU per tick | share of 20 ms |\n|---|---|---|")
    for size in (1, 5, 10, 25, 50):
        rec = telemetry.open_recording(telemetry.RerunTarget("save", str(folder / f"batch{size}.rrd")),
                                       telemetry.default_blueprint())
        log_static(rec, vehicle, None)
        batches = [TickColumns.from_records(ticks[i:i + size]) for i in range(0, len(ticks) - size + 1, size)]
        start = time.thread_time()
        for batch in batches:
            send_ticks(rec, batch, vehicle)
        cost = (time.thread_time() - start) / (len(batches) * size)
        telemetry.finish(rec)
        print(f"| {size} | {cost * 1e3:.3f} ms | {100 * cost / PERIOD:.2f} % |")


def paced_loop(ticks: list[TickRecord], sink) -> tuple[np.ndarray, np.ndarray]:
    """Run the ticks at 50 Hz; returns how late each wake-up was and how long each log_tick took (s)."""
    allocator = Allocator.for_vehicle(load_vehicle(), 16.0)
    late, calls = np.zeros(len(ticks)), np.zeros(len(ticks))
    deadline = time.perf_counter()
    for k, record in enumerate(ticks):
        deadline += PERIOD
        time.sleep(max(deadline - time.perf_counter(), 0.0))
        late[k] = time.perf_counter() - deadline
        thrusts, _ = allocator.thrusts(record.tau)     # the runner's own work per tick
        thrusts_to_pwms(thrusts, record.battery_voltage)
        if sink is not None:
            start = time.perf_counter()
            sink.log_tick(record)
            calls[k] = time.perf_counter() - start
    return late, calls


def loop_costs(ticks: list[TickRecord], folder: Path) -> None:
    vehicle = load_vehicle()
    print("\n| 50 Hz loop | in log_tick (mean / max) | sink thread CPU per tick | total per tick | share of 20 ms "
          "| wake-up late p50 / p99 / max | dropped |\n|---|---|---|---|---|---|---|")
    late, _ = paced_loop(ticks, None)
    print(f"| no sink | - | - | - | - | {_late(late)} | - |")
    rec = telemetry.open_recording(telemetry.RerunTarget("save", str(folder / "live.rrd")),
                                   telemetry.default_blueprint())
    sink = telemetry.RerunSink(rec, vehicle)
    late, calls = paced_loop(ticks, sink)
    sink.close()
    s = sink.stats
    total = s.call_per_tick + s.work_per_tick
    print(f"| Rerun sink | {s.call_per_tick * 1e6:.1f} / {max(calls) * 1e6:.0f} us | {s.work_per_tick * 1e3:.3f} ms "
          f"| {total * 1e3:.3f} ms | {100 * total / PERIOD:.2f} % | {_late(late)} | {s.dropped} |")


def tick_costs(ticks: list[TickRecord], rounds: int = 4) -> None:
    """The runner's tick computation from each recorded state, prediction on and off in alternating rounds."""
    vehicle = load_vehicle()
    actuation = Actuation(vehicle, max_thrust=40.0)
    times: dict[bool, list[float]] = {True: [], False: []}
    for r in range(2 * rounds):
        predict = r % 2 == 1
        controller = Controller(vehicle, load_settings("fuzzy"))
        predictor = StatePredictor(controller.model, PERIOD)
        for tick in ticks:
            start = time.perf_counter()
            eta, nu, t_act = tick.eta, tick.nu, tick.t + HORIZON
            if predict:
                predictor.observe(tick.t, tick.eta, tick.nu)
                eta, nu = predictor.predicted(tick.t, tick.eta, tick.nu, t_act)
            out = controller.step(eta, nu, tick.reference, PERIOD)
            thrusts, _, _ = actuation.command(out.tau)
            if predict:
                predictor.commanded(t_act, actuation.allocator.matrix @ thrusts)
            times[predict].append(time.perf_counter() - start)
    print(f"\n3. a tick's computation, state -> PWMs ({len(ticks)} ticks x {rounds} rounds each, alternating):")
    for predict in (False, True):
        t = np.array(times[predict])
        print(f"   prediction {'on ' if predict else 'off'}: {_late(t)} (p50 / p99 / max); p99 is "
              f"{np.percentile(t, 99) / BUDGET:.0%} of the {BUDGET * 1e3:g} ms telemetry-in to command-out budget")


def _late(late: np.ndarray) -> str:
    p50, p99 = np.percentile(late, [50, 99]) * 1e3
    return f"{p50:.2f} / {p99:.2f} / {late.max() * 1e3:.2f} ms"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="length of each 50 Hz run (default 10)")
    args = parser.parse_args()
    ticks = records(int(args.seconds / PERIOD))
    with tempfile.TemporaryDirectory() as tmp:
        batch_costs(ticks, Path(tmp))
        loop_costs(ticks, Path(tmp))
    tick_costs(ticks)


if __name__ == "__main__":
    main()
