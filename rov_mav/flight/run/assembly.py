"""A flight assembled from what was asked (`rov-mav run`'s choices, `Choices`): the vehicle (the built-in one
started when there is no target), the session, the mission (downloaded from the vehicle when asked), the limits, the
allocation and the law warmed up, the recorders, the runner; flown; then its metrics. The command parses and
reports; this builds, flies and closes, on every exit path: the link, the built-in vehicle and every sink closed.

What flight/ may not import is handed in: the built-in vehicle's launch (`BuiltIn`: sim_bridge's process) and the
Rerun sink (the command line's --rerun).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

from rov_mav.control.controller import Controller, ControllerSettings
from rov_mav.flight.record.runlog import RunLog
from rov_mav.flight.record.status import StatusLine
from rov_mav.flight.run.guided import KIND as GUIDED_KIND
from rov_mav.flight.run.guided import GuidedStream
from rov_mav.flight.run.run_options import DEFAULT_MAX_TILT_DEG, Limits, RunOptions, RunResult
from rov_mav.flight.run.runner import Runner, warm_up
from rov_mav.flight.session.link import Session
from rov_mav.flight.thrusters.actuation import Actuation
from rov_mav.mission.metrics import run_metrics, terrain_metrics, truth_metrics
from rov_mav.mission.missions import Mission
from rov_mav.model.vehicle import Vehicle


@dataclass(frozen=True)
class LimitFlags:
    """The limits asked on the command line (None: the mission's own)."""

    max_depth: float | None = None
    max_tracking_error: float | None = None
    max_thrust: float | None = None
    max_tilt_deg: float | None = None


def run_limits(mission: Mission, flags: LimitFlags) -> Limits:
    """Each flag, else the mission's own; a path deeper than --max-depth is refused here (ConfigError)."""
    own = mission.limits
    if flags.max_depth is not None:
        mission.check_depth(flags.max_depth, "--max-depth")
    tilt = math.radians(flags.max_tilt_deg) if flags.max_tilt_deg is not None else own.max_tilt
    return Limits(max_depth=flags.max_depth or own.max_depth,
                  max_tracking_error=flags.max_tracking_error or own.max_tracking_error,
                  max_thrust=flags.max_thrust or own.max_thrust,
                  max_tilt=tilt if tilt is not None else math.radians(DEFAULT_MAX_TILT_DEG))


class BuiltIn(Protocol):
    """The built-in vehicle in a process of its own, loading once made: `start` starts its clock (LinkError),
    `stop` ends it."""

    def start(self) -> None: ...

    def stop(self) -> None: ...


@dataclass(frozen=True)
class Choices:
    """What a run was asked, as the command line parsed it."""

    mission: Mission | None                 # None: the mission stored on the vehicle
    model: Vehicle
    settings: ControllerSettings | None     # None: ArduSub's GUIDED flies the reference (no law of ours)
    options: RunOptions                     # with the mission's limits (`run_limits`) when it is known
    limit_flags: LimitFlags
    target: str | None                      # None: the built-in vehicle
    sysid: int
    baud: int
    speedup: float
    key: bytes | None
    guided_rate: float
    log: str | None
    diffuse: bool
    pretension: bool

    @property
    def kind(self) -> str:
        return GUIDED_KIND if self.settings is None else self.settings.kind


class Flight:
    """One run, built in `open`, flown by `fly`, closed by `close` (whatever happened before)."""

    def __init__(self, choices: Choices, launch: Callable[[Mission], tuple[BuiltIn, str]] | None,
                 recording: Callable[[Mission], tuple[object, object | None]],
                 mission_from_vehicle: Callable[[Session], Mission]):
        self.choices = choices
        self.mission = choices.mission
        self._launch, self._recording, self._from_vehicle = launch, recording, mission_from_vehicle
        self.builtin: BuiltIn | None = None
        self.session: Session | None = None
        self.rerun_target = self.rerun = self.actuation = self.controller = None
        self.sinks: list = [StatusLine()]
        self.options = choices.options
        self._flying = False

    @property
    def true_disturbance(self):
        """The built-in vehicle's constant disturbance (known: it is ours), else None."""
        return self.mission.environment.constant_disturbance if self.builtin is not None else None

    def open(self) -> None:
        """The vehicle, the link, the mission and the law. What is slow to start goes first when the vehicle is the
        built-in one: its clock runs from its start, under the mission's disturbance (at --speedup 10 a second of
        loading would be ten of drift before the first tick); its own process loads meanwhile."""
        c = self.choices
        target = c.target
        if target is None:
            self.builtin, target = self._launch(self.mission)
            self._prepare_compute()
            self.builtin.start()
        self.session = Session.open(target, sysid=c.sysid, baud=c.baud, rate_hint=c.speedup, signing_key=c.key)
        if self.mission is None:
            self.mission = self._from_vehicle(self.session)
            self.options = dataclasses.replace(c.options, limits=run_limits(self.mission, c.limit_flags))
        if self.actuation is None:
            self._prepare_compute()

    def _prepare_compute(self) -> None:
        """The recording, the allocation and the law, and their first-call costs (imports, compiled code)."""
        c = self.choices
        self.rerun_target, self.rerun = self._recording(self.mission)
        guided = c.settings is None
        self.actuation = Actuation(c.model, self.options.limits.max_thrust, diffuse=c.diffuse,
                                   pretension=c.pretension, probe=self.options.thruster_check and not guided)
        self.controller = None if guided else Controller(c.model, c.settings)
        warm_up(self.mission, self.controller, self.actuation, self.options.period, self.options.approach_speed,
                own_estimate=self.options.estimator == "model")

    def fly(self) -> RunResult:
        c = self.choices
        self._flying = True
        if c.log:
            run_log = RunLog(c.log)
            run_log.write_run_info(self._run_info())
            self.session.taps.append(run_log.log_mavlink)
            self.sinks.append(run_log)
        if self.rerun is not None:
            self.sinks.append(self.rerun)
        stream = GuidedStream(self.session, c.guided_rate) if c.settings is None else None
        return Runner(self.session, self.mission, self.controller, self.actuation, self.options, self.sinks,
                      self.true_disturbance, stream).run()

    def _run_info(self) -> dict:
        c, disturbance = self.choices, self.true_disturbance
        return {"mission": self.mission.name, "mission_source": self.mission.source, "controller": c.kind,
                "rate_hz": self.options.rate, "output": self.options.output,
                "target": c.target or "built-in vehicle", "dry_run": self.options.dry_run,
                "limits": dataclasses.asdict(self.options.limits),
                "true_disturbance": None if disturbance is None else [float(v) for v in disturbance]}

    def close(self) -> None:
        """The sinks (before flying: the recording alone), the link and the built-in vehicle."""
        for sink in self.sinks if self._flying else [self.rerun] if self.rerun is not None else []:
            sink.close()
        if self.session is not None:
            self.session.close()
        if self.builtin is not None:
            self.builtin.stop()

    def metrics(self, result: RunResult) -> dict:
        """The run's metrics over the mission proper (without the lead-in to its start)."""
        flown = result.t >= 0.0
        out = run_metrics(self.mission.name, self.choices.kind, result.t[flown], result.eta[flown],
                          result.eta_d[flown], result.tau[flown], result.tau_hat[flown], self.true_disturbance,
                          result.completed)
        out.update(truth_metrics(result.truth[flown], result.eta_d[flown], result.eta[flown], result.reported[flown]))
        if result.heights is not None and self.mission.follows_terrain:
            out["terrain"] = terrain_metrics(result.t[flown], result.eta[flown], result.eta_d[flown],
                                             result.truth[flown], result.heights[flown])
        out["loop"] = result.loop_figures()
        if result.own_estimator is not None:
            out["own_estimator"] = result.own_estimator
        return out
