"""The control loop, once the vehicle is ours: a tick for each new ATTITUDE + LOCAL_POSITION_NED pair (reference ->
the state predicted to when the command acts -> law + adaptation -> allocation -> T200 map -> the output path; or
the reference to ArduSub's GUIDED), and with the prediction a tick between samples of slow telemetry (the law runs
at COMMAND_RATE at least, as the offline loop runs it at 100 Hz on its predicted state), the watchdog (stale telemetry
-> neutral; none for the link timeout -> abort),
the limits, this process's own stalls, and who else is driving (a pilot's joystick, another station's overrides,
RC input that is not ours, a mode changed: hand over)."""

from __future__ import annotations

import time
from collections import deque

import numpy as np

from rov_mav.control.controller import Controller
from rov_mav.flight.thrusters.actuation import Actuation
from rov_mav.flight.record.history import History
from rov_mav.flight.session.link import CHANNELS, mavlink, mode_name
from rov_mav.flight.run.outputs import Guided, Passthrough
from rov_mav.flight.state.own_navigation import OwnNavigation
from rov_mav.flight.state.prediction import MAX_HORIZON, StatePredictor
from rov_mav.flight.run.run_io import RunIO
from rov_mav.flight.run.run_options import MODEL, Abort, HandOver, LinkLost, VehicleFailsafe
from rov_mav.flight.record.runlog import mission_start_text
from rov_mav.flight.run.terrain_following import TerrainFollowing
from rov_mav.flight.run.thruster_watch import ThrusterWatch
from rov_mav.flight.record.tick import TickRecord
from rov_mav.flight.session.vehicle_events import EXIT_FAILSAFE, EXIT_REBOOT, RebootWatch, failsafe_text, position_lost
from rov_mav.flight.state.vehicle_state import State
from rov_mav.mission.approach import approach
from rov_mav.mission.metrics import tracking_errors
from rov_mav.mission.missions import Mission
from rov_mav.mission.terrain import VerticalLimits

STALE_REPORTS = 3                # stale-telemetry episodes (and stalls) reported one by one
STALL = 0.1                      # wall s between two turns of the loop that mean this process stalled (at least 5
STALL_PERIODS = 5                # control periods): a busy or suspended computer, not the link
RESUME_RAMP = 0.3                # vehicle s over which the first commands after a stall move from the one held
STARVED_WINDOW = 1.0             # wall s: a run stalled for more than STARVED_SHARE of it cannot control the vehicle
STARVED_SHARE = 0.5
POSITION_LOST_FOR = 1.0          # vehicle s of EKF_STATUS_REPORTs without a position that stop a run (not a flicker)
TRUTH_AGE = 0.5                  # vehicle s: a true position (SIM_STATE) this near the state's time is its truth
COMMAND_RATE = 50.0              # vehicle Hz: with the prediction, commands go out at least this often whatever the
                                 # telemetry's rate, each on the last state carried forward (the law at its own rate)
DISARM_WORDS = 5.0               # vehicle s: its texts this recent are quoted when the vehicle disarms under the run
PILOT_INPUT_LOST = "Lost manual control"   # `Sub::failsafe_pilot_input_check` (ArduSub/failsafe.cpp)


def command_period(telemetry_period: float) -> float:
    """Vehicle s between commands when the state is predicted: a telemetry period, at most 1 / COMMAND_RATE. The
    prediction's command history is kept at this resolution too: slots of a slow link's period would smear each
    command's instant over 200 ms at --rate 5 (the yaw then rang at the samples' Nyquist rate)."""
    return min(telemetry_period, 1.0 / COMMAND_RATE)


class FlightLoop:
    """`fly()` until the mission is complete (or an Abort); its logs and counts for the run's result."""

    def __init__(self, io: RunIO, mission: Mission, controller: Controller | None, actuation: Actuation,
                 output: Passthrough, sinks: list, true_disturbance: np.ndarray | None = None):
        self.io = io
        self.mission = mission
        self.controller = controller
        self.actuation = actuation
        self.output = output
        self.sinks = sinks
        self.true_disturbance = true_disturbance
        self.options = io.options
        self.period = io.options.period
        self.command_period = command_period(self.period) if controller is not None and io.options.predict else None
        self.predictor = StatePredictor(controller.model, self.command_period) \
            if self.command_period is not None else None
        self.thrusters = ThrusterWatch(controller.model, actuation, self.period, io.say) \
            if controller is not None and io.options.thruster_check and not io.options.dry_run else None
        self.last_command: list[int] | None = None    # the last flight PWMs sent
        self.lead_in: Mission | None = None
        self.t_start: float | None = None      # vehicle time of the first tick
        self.announced = False                 # the mission's start was said on the link
        self.stale = False
        self.stale_episodes = 0
        self.stalls = 0
        self.warned: set[str] = set()
        self.would_abort: str | None = None     # a dry run's first crossed limit
        self._prev_tick = 0.0                    # vehicle s of the last tick (clock)
        self._last_state_t: float | None = None  # vehicle s of the last state ticked on
        self._ticks: deque[float] = deque()
        self._stalled: deque[tuple[float, float]] = deque()   # (wall s it ended, wall s it lasted), recent stalls
        self._resumed: float | None = None      # vehicle s the loop resumed after its last stall
        self._held_tau = np.zeros(6)             # the wrench of the last command sent
        self.reboots = RebootWatch(io.session.clock)
        self._position_reported = False          # EKF_STATUS_REPORT has shown a horizontal position
        self._position_lost_at: float | None = None   # vehicle s since when it has shown none
        self.log = History(t=1, eta=6, eta_d=6, tau=6, tau_hat=6, truth=3, reported=3, heights=3)
        # altitude legs: the soundings taken in for the figures, and the depth made from them for the law (GUIDED:
        # ArduSub makes its own, from its rangefinder)
        self.terrain = TerrainFollowing(mission, VerticalLimits(max_depth=io.options.limits.max_depth), io.say) \
            if mission.follows_terrain else None
        self.loop = History(tick_time=1, latency_ms=1, horizon_ms=1, pwm=8)
        if controller is not None and io.options.estimator == MODEL:
            io.own = OwnNavigation(controller.model)     # started by a navigation source's first measurement
        io.mission_time = self.mission_time
        io.watcher = self._watch
        io.on_neutral.append(self._neutral_sent)

    def fly(self) -> None:
        io, o = self.io, self.options
        stale_after = o.stale_periods * self.period
        watch_from = io.session.clock.now()        # the watchdog counts from the loop's start at the earliest
        turned = time.perf_counter()
        while True:
            io.interrupt()
            turned = self._notice_stall(turned)
            state = io.pump(min(io.session.clock.wall_seconds(self.command_period or self.period), 0.02))
            if state is not None:
                if self._tick(state):
                    return
                continue
            seen = io.last_state.t if io.last_state is not None else watch_from
            age = io.session.clock.now() - max(seen, watch_from)
            if self._due(age, stale_after):
                if self._tick(io.last_state):     # between samples: the last state carried further forward
                    return
                continue
            if age > o.link_timeout and (state := io.pump(0.0)) is not None:
                self._tick(state)           # it was this process that stalled, not the link
                continue
            if age > o.link_timeout:
                raise LinkLost(f"link lost: no telemetry from the vehicle for {age:.1f} s of vehicle time "
                               f"(limit {o.link_timeout:g} s)")
            if age > stale_after and not self.stale:
                self._go_stale(age)

    def _go_stale(self, age: float) -> None:
        """Telemetry `age` vehicle s old: neutral on every thruster until it returns (said for the first episodes)."""
        io = self.io
        self.stale = True
        self.stale_episodes += 1
        if not self.options.dry_run:
            io.send_neutral()
            self.output.on_stale()
        if self.stale_episodes <= STALE_REPORTS:
            more = " (further episodes are counted in the final report)" if self.stale_episodes == STALE_REPORTS else ""
            io.say(f"telemetry stale ({age * 1e3:.0f} ms): neutral on all thrusters until it returns" + more,
                   "warning")

    def _backlog(self, state: State, now: float) -> bool:
        """A state older than the prediction reaches, read right after this process's own stall: the stall's backlog
        (a UDP socket that overflowed keeps its oldest datagrams and drops the newest), not a slow link. Neutral until
        fresh telemetry comes, as for stale telemetry; the link's timeout still stands."""
        if self.predictor is None or self._resumed is None or now - self._resumed > MAX_HORIZON:
            return False
        if now + self.io.session.round_trip.seconds - state.t <= MAX_HORIZON:
            return False
        if not self.stale:
            self._go_stale(now - state.t)
        return True

    def _due(self, age: float, stale_after: float) -> bool:
        """A command is due between two samples: the prediction is on, the last state is not stale, and a command
        period has passed since the last tick (slow telemetry is then flown at COMMAND_RATE, not at its own rate)."""
        if self.command_period is None or self.io.last_state is None or self._last_state_t is None:
            return False
        return age <= stale_after and self.io.session.clock.now() - self._prev_tick >= self.command_period

    def mission_time(self, t: float) -> float:
        """Vehicle s since the mission proper started (negative during the lead-in); across a reboot of the vehicle
        (its clock restarted) as if its clock had run on."""
        if self.t_start is None:
            return 0.0
        lead = self.lead_in.duration if self.lead_in is not None else 0.0
        return t + self.reboots.time_lost(t) - self.t_start - lead

    def _notice_stall(self, last: float) -> float:
        """A turn of the loop much later than the last one: this process stalled (a busy computer, SIGSTOP), the
        thrusters holding its last command meanwhile. Noted, the next commands eased in from the one held
        (`RESUME_RAMP`), and a run stalled again and again for most of the last STARVED_WINDOW s stops: it cannot
        control the vehicle. Returns this turn's wall time."""
        io = self.io
        now = time.perf_counter()
        gap = now - last
        if gap <= max(STALL, io.session.clock.wall_seconds(STALL_PERIODS * self.period)):
            return now
        self.stalls += 1
        self._resumed = io.session.clock.now()
        self._stalled.append((now, gap))
        while self._stalled and self._stalled[0][0] < now - STARVED_WINDOW:
            self._stalled.popleft()
        if self.stalls <= STALE_REPORTS:
            io.say(f"this process stalled for {gap * 1e3:.0f} ms (the thrusters held its last command): easing "
                   "back in" + (" (further stalls are counted in the final report)" if self.stalls == STALE_REPORTS
                                else ""), "warning")
        share = sum(min(g, STARVED_WINDOW) for _, g in self._stalled) / STARVED_WINDOW
        if len(self._stalled) > 1 and share > STARVED_SHARE and not self.options.dry_run:
            raise Abort(f"this computer is starving the control loop: stalled {share:.0%} of the last "
                        f"{STARVED_WINDOW:g} s ({len(self._stalled)} stalls); the thrusters hold stale commands "
                        "meanwhile (run it with --realtime, or on a less busy computer)")
        return now

    def _said_before(self, now: float, since: float) -> str:
        """"; it said just before: '...'" with the vehicle's texts of the last DISARM_WORDS s of the run, or ""."""
        said = self.io.session.texts_since(max(now - DISARM_WORDS, since))
        return "; it said just before: " + "; ".join(f"'{text}'" for text in said) if said else ""

    def _watch(self, msg, kind: str) -> None:
        """While the vehicle is ours: has it failed (its failsafes, a reboot: `vehicle_events`), and is anyone else
        driving it? (VehicleFailsafe, HandOver; Abort if it rebooted or was disarmed.)"""
        s = self.io.session
        since = self.io.flying_since
        now = s.clock.now()
        self._watch_vehicle(msg, kind, now)
        if s.motor_test_stopped is not None:
            raise Abort(s.motor_test_stopped + self._said_before(now, since))
        if kind == "HEARTBEAT":
            if not msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED:
                raise Abort("the vehicle was disarmed during the run (a failsafe, or another station)"
                            + self._said_before(now, since))
            if msg.custom_mode != self.output.flight_mode:
                mode = mode_name(msg.custom_mode)
                if mode == "SURFACE":
                    raise VehicleFailsafe("the vehicle entered SURFACE (a failsafe's action, or a pilot): left to "
                                          "it", now, EXIT_FAILSAFE)
                raise HandOver(f"the vehicle's mode was changed to {mode} by someone else", now)
        stations = s.stations
        if moving := stations.pilots_moving(since):
            raise HandOver(f"pilot takeover: {moving[0].describe()}", moving[0].deflected_at, moving[0])
        if overriding := stations.overriding(since):
            raise HandOver(f"another station took over the thrusters: {overriding[0].describe()}",
                           overriding[0].last_drive, overriding[0])
        if self.io.changes.gcs is None and (joysticks := stations.joysticks(since, s.sysid)):
            raise HandOver(f"a pilot station on our GCS sysid started sending MANUAL_CONTROL, which ArduSub "
                           f"writes over our thrusters: {joysticks[0].describe()}", joysticks[0].last_drive,
                           joysticks[0])
        if joined := stations.joined(since, {s.sysid}):
            raise HandOver(f"a ground station appeared mid-run on our GCS sysid {s.sysid} (ArduSub writes its "
                           f"joystick over our thrusters): {joined[0].describe()}",
                           joined[0].first_seen, joined[0])
        # what the vehicle reports: someone on another link (whose messages we never see) writing its RC input -
        # unless the vehicle's own pilot-input failsafe just rewrote it (channels 1-6 to neutral, 7-8 kept: this run
        # was silent too long), which is no other station's doing
        if kind == "RC_CHANNELS" and s.echo.rc(rc := [getattr(msg, f"chan{i}_raw") for i in range(1, 17)]):
            foreign = (f"the vehicle's RC input is not what this run sends (RC_CHANNELS 1-16 {rc}): another station "
                       "is writing it")
        elif kind == "SERVO_OUTPUT_RAW" and self.output.outputs_echo_overrides and \
                s.echo.servo(out := [getattr(msg, f"servo{i}_raw") for i in self.io.motors.outputs]):
            foreign = (f"the thrusters' outputs are not what this run sends (SERVO_OUTPUT_RAW {out}): another station "
                       "is writing the RC input they pass through")
        else:
            return
        if any(text.startswith(PILOT_INPUT_LOST) for text in s.texts_since(max(now - DISARM_WORDS, since))):
            raise Abort(f"the vehicle's pilot-input failsafe acted while this run was silent (it said just before: "
                        f"'{PILOT_INPUT_LOST}')")
        raise HandOver(foreign, now)

    def _watch_vehicle(self, msg, kind: str, now: float) -> None:
        """The vehicle's own trouble: a reboot (its clock went back, or it reports booting), a failsafe it announces,
        its estimator without a position."""
        if (reboot := self.reboots.while_flying(msg, kind, now)) is not None:
            raise Abort(reboot, EXIT_REBOOT)
        if kind == "STATUSTEXT" and (fault := failsafe_text(msg.text)) is not None and fault.stop:
            raise VehicleFailsafe(f"the vehicle's failsafe: {fault.name} (\"{msg.text}\")", now, EXIT_FAILSAFE)
        if kind == "EKF_STATUS_REPORT":
            if not position_lost(msg.flags):
                self._position_reported, self._position_lost_at = True, None
            elif self._position_reported:
                self._position_lost_at = now if self._position_lost_at is None else self._position_lost_at
                if now - self._position_lost_at >= POSITION_LOST_FOR:
                    raise VehicleFailsafe(f"the vehicle's estimator has lost its horizontal position for "
                                          f"{now - self._position_lost_at:.1f} s (EKF_STATUS_REPORT flags "
                                          f"0x{msg.flags:04x}): no position to fly on", now, EXIT_FAILSAFE)

    def _tick(self, state: State) -> bool:
        """One control tick; True when the mission is complete."""
        io, o = self.io, self.options
        now = io.session.clock.now()
        if self.t_start is None:
            self.t_start = state.t
            self.lead_in = approach(state.eta, self.mission.start_pose, o.approach_speed)
            if self.lead_in is not None:
                io.say(f"lead-in to the mission's start pose: {self.lead_in.duration:.1f} s")
            self._prev_tick = now - self.period
        if self._backlog(state, now):
            return False
        fresh = state.t != self._last_state_t      # a new sample, not the last one carried further
        self._last_state_t = state.t
        if self.stale:
            self.stale = False
            if self.stale_episodes <= STALE_REPORTS:
                io.say("telemetry back: control resumed")
        t = self.mission_time(state.t)
        if t >= 0 and not self.announced and not o.dry_run:
            self.announced = True
            io.session.announce(mission_start_text(state.t - t))
        dt = min(max(now - self._prev_tick, 0.0), o.stale_periods * self.period)
        self._prev_tick = now
        reference = self._reference(t)
        if self.terrain is not None:
            self.terrain.observe(io.soundings.take(), float(state.eta[2]))
            if not isinstance(self.output, Guided):
                reference = self.terrain.shape(t, state.t, reference, dt)
        horizon = 0.0
        if isinstance(self.output, Guided):
            out, thrusts = self.output.stream.output, np.full(CHANNELS, np.nan)
            pwm = io.decoder.servo[:CHANNELS] if io.decoder.servo is not None else np.full(CHANNELS, np.nan)
            self._check_limits(state, reference)
            leg = self.mission.terrain(t) if t >= 0 else None
            self.output.stream.tick(state.t, reference, send=not o.dry_run, height=leg[1] if leg else None)
        else:
            eta, nu, t_act = state.eta, state.nu, now + io.session.round_trip.seconds
            if fresh and self.thrusters is not None:     # on the vehicle's own state: not on a model's estimate
                jumps = io.decoder.shaping.jumps.jumps
                if jumps and jumps[-1].seen == state.t:  # the estimate jumped: not a thruster's doing
                    self.thrusters.health.estimate_jumped(state.t)
                vehicle = io.vehicle_state
                self.thrusters.observe(state.t, np.concatenate([vehicle.eta, vehicle.nu]))
            if self.predictor is not None:
                if t_act - state.t > MAX_HORIZON and not o.dry_run:
                    raise Abort(f"the state is {t_act - state.t:.2f} s old when its command acts (round trip "
                                f"{io.session.round_trip.seconds * 1e3:.0f} ms): beyond the {MAX_HORIZON:g} s this "
                                "run predicts; a link this slow cannot fly the mission")
                if fresh:
                    self.predictor.observe(state.t, state.eta, state.nu)
                eta, nu = self.predictor.predicted(state.t, state.eta, state.nu, t_act)
                horizon = t_act - state.t if eta is not state.eta else 0.0
            out = self.controller.step(eta, nu, self._ahead(t, horizon) if horizon else reference, dt)
            tau = self._eased(out.tau)
            if io.decoder.voltage is not None:
                self.actuation.set_voltage(io.decoder.voltage)
            thrusts, pwm, _ = self.actuation.command(tau, t_act)
            self._check_limits(state, reference)
            if not o.dry_run:
                self.last_command = self.output.send(pwm)
            self._commanded(t_act, self.actuation.allocator.wrench(thrusts * self.actuation.gains))
            if self.thrusters is not None:
                self.thrusters.told(t_act, self.actuation.delivered, tau)
        # telemetry in -> command out, for a new sample's tick (a tick between samples answers no telemetry)
        latency = time.perf_counter() - state.received if fresh else float("nan")
        age = io.session.clock.now() - state.t
        self._count_tick(state.t, latency, horizon, pwm)
        truth = io.truth.position if io.truth.t is not None and abs(io.truth.t - state.t) <= TRUTH_AGE else None
        reported = state.reported if state.reported is not None else state.eta[:3]
        heights = self._heights(t, state.t)
        if t >= 0 and fresh:
            self.log.append(t=t, eta=state.eta, eta_d=reference[:6], tau=out.tau, tau_hat=out.tau_hat,
                            truth=truth if truth is not None else np.full(3, np.nan), reported=reported,
                            heights=[heights.get(k, np.nan) for k in ("height", "height_true", "height_target")])
        record = TickRecord(t=t, vehicle_time=state.t, eta=state.eta, nu=state.nu, reference=reference, tau=out.tau,
                            tau_hat=out.tau_hat, s=out.s, gamma=out.gamma, thrusts=thrusts, pwm=pwm,
                            progress=self.mission.progress(t), telemetry_age=age, latency=latency,
                            control_rate=len(self._ticks), battery_voltage=self.actuation.voltage, horizon=horizon,
                            true_disturbance=self.true_disturbance, truth=truth, reported=reported,
                            **{k: v for k, v in heights.items() if k != "height_target"})
        for sink in self.sinks:
            sink.log_tick(record)
        return t >= self.mission.duration

    def _reference(self, t: float) -> np.ndarray:
        """The reference (18,) at mission time t: the lead-in's before 0."""
        return self.mission.reference(t) if t >= 0 else self.lead_in.reference(t + self.lead_in.duration)

    def _ahead(self, t: float, horizon: float) -> np.ndarray:
        """The reference `horizon` s after mission time t, for the predicted state (an altitude leg's depth carried
        forward at its rate)."""
        reference = self._reference(t + horizon)
        return self.terrain.ahead(reference, horizon) if self.terrain is not None else reference

    def _heights(self, t: float, vehicle_t: float) -> dict:
        """The tick's height fields on an altitude or standoff leg (the sounding taken in, the truth's, the surface's
        estimate, the leg's own); none elsewhere."""
        leg = self.mission.terrain(t) if self.terrain is not None and t >= 0 else None
        if leg is None:
            return {}
        truth = self.io.truth
        true = truth.ice_gap if leg[0] == "standoff" else truth.height
        fresh = truth.height_t is not None and abs(truth.height_t - vehicle_t) <= TRUTH_AGE
        return {"height": self.terrain.height, "height_true": true if true is not None and fresh else np.nan,
                "surface": self.terrain.surface, "height_target": leg[1]}

    def _eased(self, tau: np.ndarray) -> np.ndarray:
        """The law's wrench, eased in from the one held during a stall over RESUME_RAMP vehicle s after it: the
        first command after a stall is not the whole correction of an error that grew while nothing was sent."""
        if self._resumed is None:
            return tau
        share = (self.io.session.clock.now() - self._resumed) / RESUME_RAMP
        if share >= 1.0:
            self._resumed = None
            return tau
        return self._held_tau + max(share, 0.0) * (tau - self._held_tau)

    def _commanded(self, t_act: float, wrench: np.ndarray) -> None:
        """The wrench just sent (zero for neutral), acting from vehicle time t_act: held for the next stall and
        known to the prediction."""
        self._held_tau = wrench
        if self.io.own is not None:
            self.io.own.commanded(t_act, wrench)
        if self.predictor is not None:
            self.predictor.commanded(t_act, wrench)

    def _neutral_sent(self) -> None:
        """Neutral went out instead of a command: no thrust carried over, and none predicted."""
        self.actuation.reset()
        session = self.io.session
        self._commanded(session.clock.now() + session.round_trip.seconds, np.zeros(6))

    def _count_tick(self, t: float, latency: float, horizon: float, pwm: np.ndarray) -> None:
        self._ticks.append(t)
        while self._ticks and self._ticks[0] <= t - 1.0:
            self._ticks.popleft()
        self.loop.append(tick_time=t, latency_ms=latency * 1e3, horizon_ms=horizon * 1e3, pwm=pwm[:CHANNELS])

    def _check_limits(self, state: State, reference: np.ndarray) -> None:
        lim = self.options.limits
        crossed = []
        if lim.max_depth is not None and state.eta[2] > lim.max_depth:
            crossed.append(f"depth {state.eta[2]:.2f} m > max_depth {lim.max_depth:g} m")
        tilt = max(abs(state.eta[3]), abs(state.eta[4]))
        if lim.max_tilt is not None and tilt > lim.max_tilt:
            crossed.append(f"tilt {np.degrees(tilt):.1f} deg (roll {np.degrees(state.eta[3]):.1f}, pitch "
                           f"{np.degrees(state.eta[4]):.1f}) > max_tilt {np.degrees(lim.max_tilt):g} deg")
        if lim.max_tracking_error is not None:
            error = float(tracking_errors(state.eta[None], reference[None, :6])[0][0])
            if error > lim.max_tracking_error:
                crossed.append(f"tracking error {error:.2f} m > max_tracking_error {lim.max_tracking_error:g} m")
        servo = self.io.decoder.servo
        if lim.max_thrust is not None and servo is not None and self.actuation.beyond_cap(servo).any():
            crossed.append(f"thruster outputs {servo.astype(int).tolist()} us (SERVO_OUTPUT_RAW) beyond the "
                           f"{self.actuation.describe_range()} that max_thrust {lim.max_thrust:g} N allows")
        if not crossed:
            return
        if not self.options.dry_run:
            raise Abort("limit crossed: " + "; ".join(crossed))
        self.would_abort = self.would_abort or "limit crossed: " + "; ".join(crossed)
        for text in crossed:
            kind = text.split(" ")[0]
            if kind not in self.warned:
                self.warned.add(kind)
                self.io.say(f"dry run: would abort here: {text}", "warning")
