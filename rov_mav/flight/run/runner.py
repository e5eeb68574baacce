"""A run against a vehicle, phase by phase, each in a module of its own:

1. claim (`flight.run.claim`): identify the vehicle, watch the link sending nothing, refuse one that is someone else's;
   then the GCS role, abandoned outputs neutral, the telemetry the law needs at its rate.
2. take over (`flight.run.outputs`): the output path's own way to the thrusters -- RCIN passthrough, ArduSub's motor
   test, or GUIDED -- after neutral overrides are held and proven.
3. fly (`flight.run.control_loop`): a tick per new state, the watchdog, the limits, stalls of this process, and a hand
   over to whoever else starts driving.
4. the safe stop (`flight.run.safe_stop`), on every exit path, completion, signals, errors and hand-overs included: what
   the run changed on the vehicle (`flight.session.vehicle_changes`) undone step by step, each step confirmed or named.
What they share -- the link read into the state, the sinks told, neutral, the signal that stops the run -- is
`flight.run.run_io`.
"""

from __future__ import annotations

import os
import signal
import traceback

import numpy as np

from rov_mav.control.controller import Controller
from rov_mav.flight.thrusters.actuation import Actuation
from rov_mav.flight.run.claim import FRAME, MOTORS, THRUSTERS, VehicleClaim
from rov_mav.flight.run.control_loop import STALL, FlightLoop
from rov_mav.flight.run.guided import GuidedStream
from rov_mav.flight.session.link import LinkError, Session
from rov_mav.flight.state.model_estimator import ModelEstimator
from rov_mav.flight.run.outputs import Guided, MotorTest, Passthrough
from rov_mav.flight.state.prediction import StatePredictor
from rov_mav.flight.run.run_io import RunIO
from rov_mav.flight.run.run_options import MOTOR_TEST, Abort, HandOver, RunOptions, RunResult
from rov_mav.flight.run.safe_stop import SafeStop
from rov_mav.flight.session.vehicle_changes import VehicleChanges
from rov_mav.mission.approach import approach
from rov_mav.mission.metrics import tracking_errors
from rov_mav.mission.missions import Mission

# Ctrl-C, kill, a closed terminal or ssh session, Ctrl-\: each ends in the safe stop.
HANDLED_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP, signal.SIGQUIT)


def warm_up(mission: Mission, controller: Controller | None, actuation: Actuation, period: float,
            approach_speed: float, own_estimate: bool = False) -> None:
    """One tick's computations, so that the first real tick pays no first-call (compile, import) costs. The caller
    runs it before the Runner takes the vehicle (`rov-mav run` before even starting its built-in vehicle); with
    `own_estimate`, the run's own filter's (`--estimator model`: its model is compiled on first use, seconds on a
    fresh install, which must not come with the first acoustic fix in flight)."""
    reference = mission.reference(0.0)
    eta = reference[:6] + 0.1
    if controller is not None:
        controller.step(eta, np.zeros(6), reference, period)
        controller.reset()
        predictor = StatePredictor(controller.model, period)
        predictor.commanded(0.0, np.ones(6))
        predictor.observe(0.0, eta, np.zeros(6))
        predictor.observe(period, eta, np.zeros(6))
        predictor.predicted(period, eta, np.zeros(6), 3.5 * period)
        if own_estimate:
            filter_ = ModelEstimator(controller.model)
            filter_.start(0.0, eta, np.zeros(6))
            filter_.commanded(0.0, np.ones(6))
            filter_.advance(period, np.zeros(6))
            filter_.fix(period, float(eta[0]), float(eta[1]), 0.1)
    actuation.command(np.full(6, 1e3))          # the bounded (saturated) allocation path too
    actuation.command(np.zeros(6))
    actuation.reset()
    approach(eta, mission.start_pose, approach_speed)
    tracking_errors(eta[None], reference[None, :6])


class Runner:
    """Flies `mission` with `controller` (or ArduSub's GUIDED with `guided`) over `session`: claim, take over, fly,
    and the safe stop on every exit; every sink gets log_tick / log_event / close."""

    def __init__(self, session: Session, mission: Mission, controller: Controller | None, actuation: Actuation,
                 options: RunOptions, sinks: list, true_disturbance: np.ndarray | None = None,
                 guided: GuidedStream | None = None):
        self.session = session
        self.options = options
        self.changes = VehicleChanges()
        self.io = RunIO(session, options, self.changes, sinks)
        if guided is not None:
            self.output, needs = Guided(self.io, guided), FRAME
        elif options.output == MOTOR_TEST:
            self.output, needs = MotorTest(self.io), MOTORS
        else:
            self.output, needs = Passthrough(self.io), THRUSTERS
        self.loop = FlightLoop(self.io, mission, controller, actuation, self.output, sinks, true_disturbance)
        self.claim = VehicleClaim(self.io, actuation.set_directions, actuation.vehicle, needs)
        self.round_trip_ms = float("nan")
        if session.rejections is not None:
            session.rejections.on_first = lambda r: self.io.say(
                f"ignoring MAVLink not signed with our key (the first: {r.describe()}); counted, reported at the end",
                "warning")

    def run(self) -> RunResult:
        previous = {s: signal.signal(s, self._on_signal) for s in HANDLED_SIGNALS}
        self.session.interrupt = self.io.interrupt
        completed, code, reason, handover = False, 0, "mission complete", None
        try:
            self.claim.claim()
            if not self.options.dry_run:
                self.output.take_over()
            self.loop.fly()
            completed = True
            if self.loop.would_abort is not None:     # a dry run that crossed a limit did not fly a mission
                code, reason = 1, f"dry run: it would have aborted ({self.loop.would_abort})"
        except Abort as exc:
            code, reason = exc.code, exc.reason
            handover = exc if isinstance(exc, HandOver) else None
        except LinkError as exc:
            code, reason = 1, str(exc)
        except Exception as exc:     # noqa: BLE001 -- any bug must still end in a safe stop
            code, reason = 1, f"internal error: {exc!r}"
            self.io.say(traceback.format_exc().rstrip(), "error")
        finally:
            self.io.stopping = True
            self.session.interrupt = None
            trip = self.session.round_trip
            self.round_trip_ms = trip.seconds * 1e3 if trip.samples else float("nan")   # as flown, before the stop
            stop = SafeStop(self.io, self.output, handover, self.loop.last_command)
            report = stop.stop(reason, self._notes())
            named = self.loop.reboots.while_stopping(code, reason)
            if named != (code, reason):                  # a reboot first seen while stopping
                code, reason = named
                self.io.say(reason, "warning")
            if stop.unconfirmed and code == 0:     # complete, but the vehicle may not be left as it should
                code = 1
            for s, handler in previous.items():
                signal.signal(s, handler)
        return self._result(code, reason, completed, report)

    def _notes(self) -> list[str]:
        """What the stop's report says first: the delays measured and used, signing rejections, this process's
        stalls, the watchdog's episodes."""
        s, loop, notes = self.session, self.loop, []
        horizon = loop.loop.column("horizon_ms")
        if s.round_trip.samples:
            notes.append(f"delays: round trip {self.round_trip_ms:.1f} ms (TIMESYNC, median of the last "
                         f"{len(s.round_trip.samples)})" + (
                             f"; states predicted {np.percentile(horizon, 50):.1f} ms ahead (p50; p99 "
                             f"{np.percentile(horizon, 99):.1f} ms)" if loop.predictor is not None and horizon.size
                             else ""))
        if s.rejections is not None and s.rejections.count:
            notes.append(s.rejections.summary())
        if loop.stalls:
            notes.append(f"this process stalled {loop.stalls} time(s) (over {STALL * 1e3:.0f} ms between turns of "
                         "its loop): the thrusters held its last command meanwhile")
        if loop.stale_episodes:
            notes.append(f"watchdog: telemetry went stale {loop.stale_episodes} time(s) (older than "
                         f"{self.options.stale_periods:g} control periods); neutral was sent each time")
        return notes

    def _on_signal(self, signum, _frame) -> None:
        """Only record the signal: the loop (or the stop) acts on it. os.write is safe inside a handler."""
        name = signal.Signals(signum).name
        if self.io.stopping:
            try:
                os.write(2, f"\n{name} received: still stopping safely, please wait\n".encode())
            except OSError:
                pass
            return
        self.io.signal_name = self.io.signal_name or name

    def _result(self, code: int, reason: str, completed: bool, report: list[str]) -> RunResult:
        log, loop = self.loop.log, self.loop.loop
        return RunResult(
            code=code, reason=reason, completed=completed, t=log.column("t"), eta=log.column("eta"),
            eta_d=log.column("eta_d"), truth=log.column("truth"), reported=log.column("reported"),
            tau=log.column("tau"), tau_hat=log.column("tau_hat"),
            latency_ms=loop.column("latency_ms"), tick_times=loop.column("tick_time"),
            horizon_ms=loop.column("horizon_ms"), pwm=loop.column("pwm"),
            round_trip_ms=self.round_trip_ms,
            stalls=self.loop.stalls, report=report,
            own_estimator=self.io.own.figures() if self.io.own is not None else None, heights=log.column("heights"))
