"""What every phase of a run uses to reach the vehicle and the operator: reading the link (each message decoded into
the state, the vehicle's texts passed on, a watcher told of every message while flying), saying what happens to
every sink, neutral on the thrusters, and the signal that stops the run."""

from __future__ import annotations

import signal
import time
from collections.abc import Callable

import numpy as np

from rov_mav.flight.session.link import CHANNELS, NEUTRAL, Session, mavlink
from rov_mav.flight.state.own_navigation import OwnNavigation
from rov_mav.flight.run.run_options import MODEL, Abort, RunOptions
from rov_mav.flight.session.truth import Truth
from rov_mav.flight.state.soundings import Soundings
from rov_mav.flight.session.vehicle_changes import VehicleChanges
from rov_mav.flight.session.vehicle_frame import DEFAULT_OUTPUTS, MotorOutputs
from rov_mav.flight.state.vehicle_state import State, StateDecoder

SAFE_STOP_CONFIRM = 1.5          # vehicle s to see neutral in SERVO_OUTPUT_RAW


class RunIO:
    def __init__(self, session: Session, options: RunOptions, changes: VehicleChanges, sinks: list):
        self.session = session
        self.options = options
        self.changes = changes
        self.sinks = sinks
        self.decoder = StateDecoder(options.velocity_blend, steady=True)   # jumps taken in at a flyable pace
        self.motors = DEFAULT_OUTPUTS             # where the vehicle's motors are (`flight.run.claim` reads it)
        self.own: OwnNavigation | None = None     # the run's own estimator (--estimator model), while flying
        if options.estimator == MODEL:
            session.taps.append(self._navigation_source)
        self.truth = Truth()                      # where a simulator says the vehicle really is (SIM_STATE)
        self.soundings = Soundings()              # an echo sounder's readings, from whichever component sends them
        session.taps.append(self._sounding)
        self._jumps_said = 0
        self._own_said = False
        self.last_state: State | None = None      # the state the law flies on
        self.vehicle_state: State | None = None   # ... and the vehicle's, as it reports it (the same sample)
        self.signal_name: str | None = None
        self.stopping = False
        self.rc_seen: list[list[int]] | None = None     # RC_CHANNELS rows, while the claim observes
        self.flying_since: float | None = None    # vehicle s the vehicle became ours to fly (armed by us)
        self.watcher: Callable[[object, str], None] | None = None   # while flying: is anyone else driving?
        self.on_neutral: list[Callable[[], None]] = []   # told whenever neutral is sent instead of a command
        self.mission_time: Callable[[float], float] = lambda t: 0.0

    def say(self, text: str, level: str = "info") -> None:
        """Tell every sink; a sink that fails (a closed terminal, a full disk) never stops the run or its stop."""
        t = self.mission_time(self.last_state.t) if self.last_state is not None else 0.0
        for sink in self.sinks:
            try:
                sink.log_event(t, text, level)
            except Exception:   # noqa: BLE001 -- reporting must not break the safe stop
                pass

    def interrupt(self) -> None:
        """Raise Abort for a signal received (SIGINT, SIGTERM, ...), unless the run is already stopping."""
        if self.signal_name is not None and not self.stopping:
            signum = signal.Signals[self.signal_name]
            raise Abort(f"stopped by {self.signal_name}", 128 + signum)

    def pump(self, timeout: float) -> State | None:
        """Read what arrived within `timeout` wall s; returns the newest complete state, if any."""
        received = None
        for msg, wall in self.session.poll(timeout):
            if self.track(msg):
                received = wall
        if received is None:
            return None
        self.vehicle_state = self.decoder.state(received)
        self.last_state = self.vehicle_state if self.own is None else self.own.state(self.vehicle_state)
        flying_own = self.own is not None and self.own.started_by is not None
        if flying_own and not self._own_said:
            self._own_said = True
            self.say(f"flying on the run's own estimate from here: {self.own.started_by} started it")
        jumps = self.decoder.shaping.jumps.jumps
        while self._jumps_said < len(jumps):
            text = jumps[self._jumps_said].describe()
            self.say(f"the vehicle's estimate: {text}; the run flies its own" if flying_own else text, "warning")
            self._jumps_said += 1
        return self.last_state

    def pump_for(self, vehicle_seconds: float) -> None:
        end = time.monotonic() + self.session.clock.wall_seconds(vehicle_seconds)
        while time.monotonic() < end:
            self.interrupt()
            self.pump(0.01)

    def track(self, msg) -> bool:
        """Decode one message (True if it completes a state); pass on the vehicle's texts; the watcher sees it."""
        kind = msg.get_type()
        if kind == "STATUSTEXT":
            self.say(f"vehicle: {msg.text}", "warning" if msg.severity <= mavlink.MAV_SEVERITY_WARNING else "info")
        elif kind == "RC_CHANNELS" and self.rc_seen is not None:
            self.rc_seen.append([getattr(msg, f"chan{i}_raw") for i in range(1, CHANNELS + 1)])
        if self.watcher is not None and self.flying_since is not None and not self.stopping:
            self.watcher(msg, kind)
        if self.truth.origin is None:          # sent once (ArduSub: when the origin is set), maybe while a wait read
            for origin in self.session.origins.values():
                self.truth.update(origin, 0.0)
        self.truth.update(msg, self.session.clock.now())
        return self.decoder.update(msg)

    def _navigation_source(self, msg, outgoing: bool) -> None:
        """Every message heard (whoever sent it: the navigation sources speak from their own ids) to our estimator."""
        if self.own is not None and not outgoing:
            self.own.source(msg, self.session.clock.now(), self.truth.origin)

    def _sounding(self, msg, outgoing: bool) -> None:
        if not outgoing:
            self.soundings.update(msg, self.session.clock.now())

    def send_neutral(self) -> None:
        """Neutral on all eight channels (and in the motor test, when one runs), no waiting."""
        self.session.send_override([NEUTRAL] * CHANNELS)
        if self.session.motor_test is not None:
            self.session.send_motor_test([NEUTRAL] * CHANNELS)
        for hook in self.on_neutral:
            hook()
        self.changes.overrides_sent = True

    @property
    def motors(self) -> MotorOutputs:
        return self._motors

    @motors.setter
    def motors(self, motors: MotorOutputs) -> None:
        """Where the motors are: the outputs read for them in SERVO_OUTPUT_RAW follow."""
        self._motors = motors
        self.decoder.outputs = motors.outputs

    def neutral_confirmed(self, confirm: float = SAFE_STOP_CONFIRM, slack: float = 0.3) -> bool:
        """Send neutral and wait up to `confirm` vehicle s (plus `slack` wall s) for SERVO_OUTPUT_RAW showing 1500
        on the motors' outputs."""
        self.send_neutral()
        self.decoder.servo = None
        deadline = time.monotonic() + self.session.clock.wall_seconds(confirm) + slack
        while time.monotonic() < deadline:
            self.pump(0.01)
            if self.decoder.servo is not None:
                if np.all(np.abs(self.decoder.servo - NEUTRAL) <= 1):
                    return True
                self.decoder.servo = None          # still the old outputs: wait for the next report
        return False

    def answering(self) -> bool:
        """Has the vehicle sent anything recently (within the link timeout)?"""
        clock = self.session.clock
        if not clock.started:
            return False
        self.pump(0.05)
        return clock.now() - clock.last_vehicle <= self.options.link_timeout and \
            time.perf_counter() - clock.last_wall <= clock.wall_seconds(self.options.link_timeout)
