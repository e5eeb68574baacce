"""The real-time loop against a vehicle: safe start, control ticks on the vehicle's telemetry, watchdog, limits, and
a safe stop on every exit path.

Start: identify the vehicle (ArduSub on a sub), then watch the link for a few seconds with nothing sent but reads:
refuse a vehicle that is someone else's (armed, driven by another station, RC input changing) before anything goes
out (`stations.judge`). Only then: take the GCS role if a pilot's joystick shares the GCS sysid, make abandoned
passthrough outputs neutral, ask for the telemetry the law needs and check its rate, hold neutral overrides, switch
the eight outputs to RCIN passthrough (each confirmed), MANUAL, arm.
Flying: a pilot's joystick beyond the dead band, another station's RC override, a joystick appearing on our GCS
sysid, RC input that is not ours, or a mode changed by someone else hands the vehicle to the pilot (`PilotTakeover`).
Tick (each new ATTITUDE + LOCAL_POSITION_NED pair): reference -> law + adaptation -> allocation -> T200 map ->
RC_CHANNELS_OVERRIDE, a TickRecord to every sink. When the mission proper starts (after the lead-in) the run says so
on the link, in vehicle time (`runlog.mission_start_text`), so that any telemetry log of the dive aligns with it.
With a GuidedStream instead of a law (`--controller ardusub-guided`, flight/guided.py): no passthrough, GUIDED
instead of MANUAL, the tick sends the reference to the vehicle's own position controller; the stop first leaves
GUIDED for MANUAL (so neutral can be confirmed) and ends by setting back the mode it found.
With `output` MOTOR_TEST the outputs stay on their motors and the tick's PWMs go out as ArduSub's motor test
(MAV_CMD_DO_MOTOR_TEST, board order, raw PWM) while neutral overrides are held as pilot input: ArduSub runs no mixer
during the test and ends it, disarming, 0.5 s after the last command, so a run killed outright (SIGKILL, a crash, a
cut tether) leaves the thrusters stopped instead of holding their last command.
Stop (completion, Ctrl-C, SIGTERM, exception, lost link, failed arm, limit crossed): neutral 1500 on all eight
channels (confirmed by SERVO_OUTPUT_RAW), release the overrides, disarm a vehicle this run armed, restore
SERVO1..8_FUNCTION and the GCS sysid, restore the message rates, and say what was done; if the vehicle no longer
answers, say that its thrusters hold their last command. A step the vehicle did not confirm (after the session's
retries) is named at the end, and a run that would have exited 0 exits 1. A pilot takeover does the same but leaves
the vehicle armed, on its motors, for the pilot.
"""

from __future__ import annotations

import os
import signal
import time
import traceback
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from rov_mav.control.controller import Controller
from rov_mav.flight.actuation import Actuation
from rov_mav.flight.guided import GuidedStream
from rov_mav.flight.history import History
from rov_mav.flight.link import CHANNELS, MANUAL, MOTOR_TEST_TIMEOUT, NEUTRAL, LinkError, Session, mavlink, mode_name
from rov_mav.flight.prediction import StatePredictor
from rov_mav.flight.runlog import mission_start_text
from rov_mav.flight.stations import Sighting, Station, Verdict, judge
from rov_mav.flight.stream_rate import measure, too_slow
from rov_mav.flight.tick import TickRecord
from rov_mav.flight.vehicle_state import State, StateDecoder
from rov_mav.mission.approach import approach
from rov_mav.mission.metrics import tracking_errors
from rov_mav.mission.missions import Mission

PASSTHROUGH_BASE = 50            # SERVOn_FUNCTION 50 + n = RCINn
MOTOR_BASE = 32                  # SERVOn_FUNCTION 32 + n = motor n
SIDE_RATES = {"SYS_STATUS": 2.0, "SERVO_OUTPUT_RAW": 10.0, "RC_CHANNELS": 2.0}   # vehicle Hz
RATE_WINDOW = 3.0                # vehicle s of telemetry measured before arming (enough to see through 30 % loss)
OBSERVE = 3.0                    # vehicle s of watching the link, sending nothing, before deciding to take it
OBSERVE_POLL = 0.25              # vehicle s between one-shot requests for RC_CHANNELS and SERVO_OUTPUT_RAW then
ROLE_SYSIDS = range(254, 200, -1)   # sysids to take the GCS role with, when a pilot's joystick holds the GCS sysid
HANDED_OVER = 3                  # exit status: the pilot took the vehicle over
NEUTRAL_HOLD = 0.3               # vehicle s of neutral before switching outputs
OVERRIDE_PROBE = 1510            # us: inside the T200 dead band at every voltage (1476-1528 us at 20 V)
PROBE_WAIT = 5.0                 # vehicle s for RC_CHANNELS (asked at 2 Hz) to echo the probe, through loss
SAFE_STOP_CONFIRM = 1.5          # vehicle s to see neutral in SERVO_OUTPUT_RAW
HANDOVER_CONFIRM = 0.2           # ... when handing over: a pilot's joystick on the GCS sysid may be writing over it
PROGRESS_EVERY = 5.0             # wall s between "still waiting" messages
STALE_REPORTS = 3                # stale-telemetry episodes reported one by one
DRY_RUN_SYSID = 254               # a dry run's own sysid: anything but the vehicle's GCS sysid
LOST_LINK_RETRY = 5.0            # wall s of neutral retries before a silent vehicle is reported as lost
MOTOR_TEST_START = 13.0          # vehicle s for the first DO_MOTOR_TEST to be accepted: ArduSub refuses one for 10 s
                                 # after an earlier test timed out, and retries a refused start every 2 s
THRUSTERS, MOTOR_TEST = "thrusters", "motor-test"   # how the PWMs reach the outputs (`RunOptions.output`)
STALL = 0.1                      # wall s between two turns of the loop that mean this process stalled (at least 5
STALL_PERIODS = 5                # control periods): a busy or suspended computer, not the link
RESUME_RAMP = 0.3                # vehicle s over which the first commands after a stall move from the one held
STARVED_WINDOW = 2.0             # wall s: a run stalled for more than STARVED_SHARE of it cannot control the vehicle
STARVED_SHARE = 0.5
# Ctrl-C, kill, a closed terminal or ssh session, Ctrl-\: each ends in the safe stop.
HANDLED_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP, signal.SIGQUIT)


class Abort(Exception):
    """The run ends early for a stated reason; `code` is the process exit status."""

    def __init__(self, reason: str, code: int = 1):
        super().__init__(reason)
        self.reason = reason
        self.code = code


class LinkLost(Abort):
    pass


class PilotTakeover(Abort):
    """Someone else is driving: hand the vehicle over (neutral, release, motors back), left armed for them."""

    def __init__(self, reason: str, t_detected: float, station: Station | None = None):
        super().__init__(reason, HANDED_OVER)
        self.t_detected = t_detected
        self.station = station


@dataclass(frozen=True)
class Limits:
    max_depth: float | None = None            # m
    max_tracking_error: float | None = None   # m
    max_thrust: float | None = None           # N per thruster
    max_tilt: float | None = None             # rad, |roll| or |pitch|


@dataclass(frozen=True)
class RunOptions:
    rate: float = 50.0                 # Hz of vehicle time: telemetry and overrides
    dry_run: bool = False
    force: bool = False
    sysid: int | None = None           # our sysid; default: the vehicle's GCS sysid parameter
    heartbeat_timeout: float = 15.0    # wall s
    position_timeout: float = 90.0     # wall s to wait for LOCAL_POSITION_NED
    stale_periods: float = 3.0         # telemetry older than this many periods -> neutral
    link_timeout: float = 2.0          # vehicle s without telemetry -> abort
    approach_speed: float = 0.2        # m/s to the mission's start pose
    velocity_blend: float = 1.0        # rad/s: below it the law's velocity is the position's rate (0: as reported)
    output: str = THRUSTERS            # THRUSTERS: RC overrides on RCIN passthrough; MOTOR_TEST: ArduSub's motor test
    predict: bool = True               # the law acts on the state predicted to when its command acts
    limits: Limits = Limits()


@dataclass
class RunResult:
    code: int
    reason: str
    completed: bool
    t: np.ndarray                      # (N,) mission ticks, vehicle s since the mission started
    eta: np.ndarray                    # (N, 6)
    eta_d: np.ndarray                  # (N, 6)
    tau: np.ndarray                    # (N, 6)
    tau_hat: np.ndarray                # (N, 6)
    latency_ms: np.ndarray             # (M,) telemetry in -> command out, every tick
    tick_times: np.ndarray             # (M,) vehicle s of every tick
    horizon_ms: np.ndarray             # (M,) how far each tick's state was predicted (0: not predicted)
    round_trip_ms: float               # the link's round trip (TIMESYNC median) at the end, nan if never measured
    stalls: int                        # times this process stalled
    report: list[str] = field(default_factory=list)

    def loop_figures(self) -> dict:
        """p50/p99 latency and prediction horizon (ms), the achieved control rate (ticks per vehicle second), the
        round trip measured and the stalls of this process."""
        span = self.tick_times[-1] - self.tick_times[0] if self.tick_times.size > 1 else 0.0
        return {
            "ticks": int(self.tick_times.size),
            "control_rate_hz": (self.tick_times.size - 1) / span if span > 0 else 0.0,
            "latency_p50_ms": _percentile(self.latency_ms, 50),
            "latency_p99_ms": _percentile(self.latency_ms, 99),
            "horizon_p50_ms": _percentile(self.horizon_ms, 50),
            "horizon_p99_ms": _percentile(self.horizon_ms, 99),
            "round_trip_ms": self.round_trip_ms,
            "stalls": self.stalls,
        }


def _percentile(values: np.ndarray, q: float) -> float:
    return float(np.percentile(values, q)) if values.size else float("nan")


def warm_up(mission: Mission, controller: Controller | None, actuation: Actuation, period: float,
            approach_speed: float) -> None:
    """One tick's computations, so that the first real tick pays no first-call (compile, import) costs. The caller
    runs it before the Runner takes the vehicle (`rov-mav run` before even starting its built-in vehicle)."""
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
    actuation.command(np.full(6, 1e3))          # the bounded (saturated) allocation path too
    actuation.command(np.zeros(6))
    actuation.reset()
    approach(eta, mission.start_pose, approach_speed)
    tracking_errors(eta[None], reference[None, :6])


class Runner:
    """Flies `mission` with `controller` over `session`; every sink gets log_tick / log_event / close."""

    def __init__(self, session: Session, mission: Mission, controller: Controller | None, actuation: Actuation,
                 options: RunOptions, sinks: list, true_disturbance: np.ndarray | None = None,
                 guided: GuidedStream | None = None):
        self.session = session
        self.guided = guided                  # instead of a law: the reference streamed to ArduSub's GUIDED mode
        self.flight_mode = guided.mode if guided is not None else MANUAL
        self.found_mode: int | None = None    # the vehicle's mode when the run took it (restored after GUIDED)
        self.mission = mission
        self.controller = controller
        self.actuation = actuation
        self.options = options
        self.sinks = sinks
        self.true_disturbance = true_disturbance
        self.decoder = StateDecoder(options.velocity_blend)
        self.period = 1.0 / options.rate
        self.saved_functions: dict[str, tuple[float, int]] = {}
        self.changed_functions: list[str] = []
        self.streams_set: list[int] = []
        self.touched = False          # an override went out
        self.armed_by_us = False
        self.saved_gcs: tuple[str, int, int] | None = None   # GCS sysid parameter changed for the run: (name, was, type)
        self.flying_since: float | None = None     # vehicle s the vehicle became ours to fly (armed by us)
        self.takeover: PilotTakeover | None = None
        self._rc_seen: list[list[int]] | None = None   # RC_CHANNELS rows, while observing
        self.signal_name: str | None = None
        self.stopping = False
        self.last_state: State | None = None
        self.last_command: list[int] | None = None    # the last flight PWMs sent
        self.lead_in: Mission | None = None
        self.t_start: float | None = None      # vehicle time of the first tick
        self.announced = False                 # the mission's start was said on the link
        self._prev_t = 0.0
        self.stale = False
        self.stale_episodes = 0
        self.unconfirmed: list[str] = []      # safe-stop steps the vehicle did not confirm
        self.warned: set[str] = set()
        self._ticks: deque[float] = deque()
        self._log = History(t=1, eta=6, eta_d=6, tau=6, tau_hat=6)
        self._loop = History(tick_time=1, latency_ms=1, horizon_ms=1)
        self.predictor = StatePredictor(controller.model, self.period) \
            if controller is not None and options.predict else None
        self.stalls = 0
        self._stalled: deque[tuple[float, float]] = deque()   # (wall s it ended, wall s it lasted), recent stalls
        self._resumed: float | None = None      # vehicle s the loop resumed after its last stall
        self._held_tau = np.zeros(6)             # the wrench of the last command sent
        if session.rejections is not None:
            session.rejections.on_first = lambda r: self.say(
                f"ignoring MAVLink not signed with our key (the first: {r.describe()}); counted, reported at the end",
                "warning")

    # -- top level -------------------------------------------------------------------------------------------

    def run(self) -> RunResult:
        previous = {s: signal.signal(s, self._on_signal) for s in HANDLED_SIGNALS}
        self.session.interrupt = self._interrupt
        completed, code, reason = False, 0, "mission complete"
        try:
            self._prepare()
            if not self.options.dry_run:
                self._take_over()
            self._fly()
            completed = True
        except Abort as exc:
            code, reason = exc.code, exc.reason
            self.takeover = exc if isinstance(exc, PilotTakeover) else None
        except LinkError as exc:
            code, reason = 1, str(exc)
        except Exception as exc:     # noqa: BLE001 -- any bug must still end in a safe stop
            code, reason = 1, f"internal error: {exc!r}"
            self.say(traceback.format_exc().rstrip(), "error")
        finally:
            self.stopping = True
            self.session.interrupt = None
            report = self._safe_stop(reason)
            if self.unconfirmed and code == 0:     # complete, but the vehicle may not be left as it should
                code = 1
            for s, handler in previous.items():
                signal.signal(s, handler)
        return self._result(code, reason, completed, report)

    def say(self, text: str, level: str = "info") -> None:
        """Tell every sink; a sink that fails (a closed terminal, a full disk) never stops the run or its stop."""
        t = self._mission_time(self.last_state.t) if self.last_state is not None else 0.0
        for sink in self.sinks:
            try:
                sink.log_event(t, text, level)
            except Exception:   # noqa: BLE001 -- reporting must not break the safe stop
                pass

    def _on_signal(self, signum, _frame) -> None:
        """Only record the signal: the loop (or the stop) acts on it. os.write is safe inside a handler."""
        name = signal.Signals(signum).name
        if self.stopping:
            try:
                os.write(2, f"\n{name} received: still stopping safely, please wait\n".encode())
            except OSError:
                pass
            return
        self.signal_name = self.signal_name or name

    def _interrupt(self) -> None:
        if self.signal_name is not None and not self.stopping:
            signum = signal.Signals[self.signal_name]
            raise Abort(f"stopped by {self.signal_name}", 128 + signum)

    # -- start -----------------------------------------------------------------------------------------------

    def _prepare(self) -> None:
        s, o = self.session, self.options
        vehicle = s.connect(o.heartbeat_timeout)
        self.say(f"vehicle: ArduSub submarine, sysid {vehicle.sysid}, on {s.target}")
        since = s.clock.now()
        passthrough = [] if o.dry_run else self._read_outputs()
        gcs = s.gcs_sysid()
        verdict = judge(self._observe(since, passthrough), s.stations, o.force)
        for station in s.stations.stations.values():
            self.say(f"also on the link: {station.describe()}")
        if verdict.refusal is not None:
            raise Abort(f"refusing to take the vehicle: {verdict.refusal}. Nothing was sent to it (--force to take "
                        "it over anyway)")
        # From here on the vehicle is ours: free, or left by a run that died.
        self._use_gcs_sysid(gcs, verdict)
        s.start_heartbeats()
        s.timesync = True            # the round trip, for the prediction and the summary
        if verdict.abandoned:
            self._neutralise(verdict.abandoned)
        for name in ("ATTITUDE", "LOCAL_POSITION_NED", *SIDE_RATES):
            msg_id = getattr(mavlink, f"MAVLINK_MSG_ID_{name}")
            hz = SIDE_RATES.get(name, o.rate)
            if s.set_message_interval(msg_id, hz):
                self.streams_set.append(msg_id)
            elif name in ("ATTITUDE", "LOCAL_POSITION_NED"):
                raise Abort(f"the vehicle refused SET_MESSAGE_INTERVAL for {name} at {hz:g} Hz")
        self._wait_for_state()
        self._check_rates()

    def _observe(self, since: float, passthrough: list[str]) -> Sighting:
        """Watch the link for OBSERVE vehicle s, sending nothing but one-shot requests for RC_CHANNELS and
        SERVO_OUTPUT_RAW (no stream rate is changed): who else is there, and is the RC input steady?"""
        s = self.session
        self._rc_seen = []
        wall_end = time.monotonic() + s.clock.wall_seconds(OBSERVE) + 1.0
        start, next_poll = None, 0.0
        while time.monotonic() < wall_end:
            self._interrupt()
            now = s.clock.now()
            start = now if start is None and s.clock.started else start
            if start is not None and now - start >= OBSERVE:
                break
            if time.monotonic() >= next_poll:
                next_poll = time.monotonic() + s.clock.wall_seconds(OBSERVE_POLL)
                s.request_message(mavlink.MAVLINK_MSG_ID_RC_CHANNELS)
                s.request_message(mavlink.MAVLINK_MSG_ID_SERVO_OUTPUT_RAW)
            self._pump(0.02)
        rc, self._rc_seen = self._rc_seen, None
        return Sighting(since=since, armed=s.armed, passthrough=passthrough, rc=rc)

    def _read_outputs(self) -> list[str]:
        """Save SERVO1..8_FUNCTION, learn MOT_1..8_DIRECTION; returns the outputs already on RCIN passthrough."""
        s = self.session
        names = [f"SERVO{n}_FUNCTION" for n in range(1, CHANNELS + 1)]
        self.saved_functions = s.get_params(names)
        missing = [n for n in names if n not in self.saved_functions]
        if missing:
            raise Abort(f"could not read {', '.join(missing)} from the vehicle")
        directions = s.get_params([f"MOT_{n}_DIRECTION" for n in range(1, CHANNELS + 1)])
        signs = [directions.get(f"MOT_{n}_DIRECTION", (1.0, 0))[0] for n in range(1, CHANNELS + 1)]
        self.actuation.set_directions(np.array(signs))
        reversed_ = [n for n, sign in enumerate(signs, 1) if sign < 0]
        if reversed_:
            self.say(f"MOT_n_DIRECTION = -1 on thruster(s) {reversed_}: passthrough and the motor test bypass it, so "
                     "their PWM is mirrored about 1500")
        stale = []
        for n in range(1, CHANNELS + 1):
            name = f"SERVO{n}_FUNCTION"
            value, ptype = self.saved_functions[name]
            if int(value) == PASSTHROUGH_BASE + n:
                self.saved_functions[name] = (float(MOTOR_BASE + n), ptype)
                stale.append(name)
        return stale

    def _neutralise(self, stale: list[str]) -> None:
        """Outputs already on RCIN passthrough (a run that lost its link?) still drive their thrusters with the
        last PWM: send neutral, and restore them to their motors when this run ends, whatever happens."""
        self.say(f"{', '.join(stale)} on RCIN passthrough with the vehicle disarmed and no station driving them for "
                 f"{OBSERVE:g} s: taken as abandoned (a run that lost its link?); sending neutral; they will be "
                 "restored to their motors when this run ends", "warning")
        self.session.override_rate = self.options.rate
        self.changed_functions += stale
        if not self._neutral():
            raise Abort("outputs left on RCIN passthrough and the vehicle does not confirm neutral")

    def _use_gcs_sysid(self, found: tuple[str, int, int] | None, verdict: Verdict) -> None:
        """Speak as the vehicle's GCS sysid (ArduSub takes RC overrides only from it). When a pilot station's
        joystick shares that sysid, ArduSub would write it over our thrusters: take the GCS role for the run with a
        sysid of our own (the parameter is restored on every exit), so ArduSub ignores the resting joystick while we
        watch it."""
        s, o = self.session, self.options
        if found is None:
            s.use_sysid(o.sysid or s.sysid)
            self.say(f"the vehicle did not report MAV_GCS_SYSID or SYSID_MYGCS: speaking as sysid {s.sysid}",
                     "warning")
            return
        name, value, ptype = found
        if o.dry_run:
            # Heartbeats from the GCS sysid would hide a lost link from the pilot's own ground station (and ArduSub
            # would count them for its GCS failsafe): a dry run, which sends no override, speaks as another sysid.
            s.use_sysid(DRY_RUN_SYSID if value != DRY_RUN_SYSID else DRY_RUN_SYSID - 1)
            self.say(f"dry run: speaking as sysid {s.sysid}, not the vehicle's GCS sysid ({name} = {value})")
            return
        pilots = [p for p in verdict.resting_pilots if p.sysid == value]
        own = o.sysid
        if own is None and pilots:
            taken = s.stations.sysids() | {s.vehicle.sysid}
            own = next(n for n in ROLE_SYSIDS if n not in taken)
        if own is None or own == value:
            if pilots:
                raise Abort(f"{pilots[0].describe()} shares the GCS sysid {value} that --sysid asks for: ArduSub "
                            "would write its joystick over our thrusters (leave --sysid out, and the run takes the GCS "
                            "role with a sysid of its own)")
            s.use_sysid(value)
            self.say(f"speaking as GCS sysid {s.sysid} ({name} = {value})")
            return
        if not s.set_param(name, own, ptype):
            raise Abort(f"the vehicle did not confirm {name} = {own}")
        self.saved_gcs = (name, value, ptype)
        s.use_sysid(own)
        why = (f": {', '.join(p.describe() for p in pilots)} is ignored by ArduSub until the run ends or hands the "
               "vehicle to it" if pilots else "")
        self.say(f"took the GCS role for this run: speaking as sysid {own}, {name} = {own} (was {value}; restored "
                 f"when the run ends){why}")

    def _wait_for_state(self) -> None:
        """Until ATTITUDE and LOCAL_POSITION_NED have both arrived, with progress messages and a timeout."""
        start = time.monotonic()
        next_note = start + PROGRESS_EVERY
        while self.decoder.attitude is None or self.decoder.position is None:
            self._interrupt()
            self._pump(0.05)
            now = time.monotonic()
            missing = self._missing_state()
            if now - start > self.options.position_timeout:
                raise Abort(f"no {missing} from the vehicle after {self.options.position_timeout:g} s: "
                            + _MISSING_HELP.get(missing, "check the link"))
            if now >= next_note:
                next_note = now + PROGRESS_EVERY
                self.say(f"waiting for {missing} ({now - start:.0f} s of {self.options.position_timeout:g} s)")

    def _missing_state(self) -> str:
        names = [n for n, m in (("ATTITUDE", self.decoder.attitude), ("LOCAL_POSITION_NED", self.decoder.position))
                 if m is None]
        return " and ".join(names)

    def _check_rates(self) -> None:
        """Measure the state messages' rates over RATE_WINDOW vehicle s: what the vehicle sends, what arrives."""
        stamps: dict[str, list[float]] = {"ATTITUDE": [], "LOCAL_POSITION_NED": []}
        t_first = None
        deadline = time.monotonic() + self.session.clock.wall_seconds(RATE_WINDOW) * 3 + 2.0
        while time.monotonic() < deadline:
            self._interrupt()
            for msg, _ in self.session.poll(0.02):
                self._track(msg)
                kind = msg.get_type()
                if kind in stamps:
                    stamps[kind].append(msg.time_boot_ms / 1000.0)
                    t_first = stamps[kind][0] if t_first is None else t_first
            if t_first is not None and self.session.clock.now() - t_first >= RATE_WINDOW:
                break
        rates = {k: measure(v) for k, v in stamps.items()}
        self.say("telemetry: " + "; ".join(f"{k} {r.describe()}" for k, r in rates.items())
                 + f" (asked {self.options.rate:g} Hz of vehicle time)")
        slow = [why for k, r in rates.items() if (why := too_slow(k, r, self.options.rate)) is not None]
        if slow:
            raise Abort("telemetry too slow for the control rate: " + "; ".join(slow))

    def _take_over(self) -> None:
        s = self.session
        s.override_rate = self.options.rate
        self._send_neutral()
        self._pump_for(NEUTRAL_HOLD)
        self._prove_overrides()
        self._send_neutral()
        self._pump_for(NEUTRAL_HOLD)
        if self.guided is not None:
            self._take_over_guided()
            return
        if self.options.output == MOTOR_TEST:
            self._take_over_motor_test()
            return
        names = [f"SERVO{n}_FUNCTION" for n in range(1, CHANNELS + 1)]
        passthrough = {name: (float(PASSTHROUGH_BASE + n), self.saved_functions[name][1])
                       for n, name in enumerate(names, 1)}
        self.changed_functions += [name for name in passthrough if name not in self.changed_functions]
        if failed := s.set_params(passthrough):
            raise Abort("the vehicle did not confirm " + ", ".join(f"{n} = {int(passthrough[n][0])}" for n in failed)
                        + " (RCIN passthrough)")
        self.say("SERVO1..8_FUNCTION set to RCIN1..8 passthrough (confirmed)")
        self._arm_in_manual()
        self.say("armed in MANUAL")

    def _arm_in_manual(self) -> None:
        s = self.session
        if s.heartbeat.custom_mode != MANUAL and not s.set_mode(MANUAL):
            raise Abort("the vehicle did not enter MANUAL mode")
        self.armed_by_us = True
        if not s.arm(True):
            raise Abort("arming failed: the vehicle refused or did not confirm it")
        self.flying_since = s.clock.now()

    def _take_over_motor_test(self) -> None:
        """MANUAL, armed, then the motor test held at neutral until the vehicle accepts it: the outputs stay on their
        motors, the neutral overrides held as pilot input (ArduSub's pilot-input failsafe disarms without it)."""
        s = self.session
        self._arm_in_manual()
        s.send_motor_test([NEUTRAL] * CHANNELS)
        start = s.clock.now()
        wall_end = time.monotonic() + s.clock.wall_seconds(MOTOR_TEST_START) + 1.0
        while s.motor_test_answers["accepted"] == 0:
            self._interrupt()
            if s.clock.now() - start > MOTOR_TEST_START or time.monotonic() > wall_end or not s.armed:
                raise Abort(f"the vehicle did not accept MAV_CMD_DO_MOTOR_TEST within {MOTOR_TEST_START:g} s "
                            f"({s.motor_test_answers['refused']} refused): ArduSub refuses it while disarmed and "
                            "for 10 s after an earlier motor test timed out (its STATUSTEXT says which)")
            self._pump(0.02)
        self.say("armed in MANUAL, the thrusters through ArduSub's motor test (MAV_CMD_DO_MOTOR_TEST, accepted): "
                 f"ArduSub stops them and disarms {MOTOR_TEST_TIMEOUT:g} s after our last command")

    def _take_over_guided(self) -> None:
        """GUIDED, then armed: the outputs stay on their motors (ArduSub's mixer), the neutral overrides held."""
        s = self.session
        self.found_mode = s.heartbeat.custom_mode
        if not s.set_mode(self.flight_mode):
            raise Abort(f"the vehicle did not enter {mode_name(self.flight_mode)} mode (ArduSub needs a position "
                        "estimate for it)")
        self.armed_by_us = True
        if not s.arm(True):
            raise Abort("arming failed: the vehicle refused or did not confirm it")
        self.flying_since = s.clock.now()
        self.say(f"armed in {mode_name(self.flight_mode)}: SET_POSITION_TARGET_LOCAL_NED (position, velocity, yaw) "
                 f"at {self.guided.rate:g} Hz of vehicle time")

    def _leave_guided(self) -> list[str]:
        """Before the neutral step: out of GUIDED to MANUAL (its mixer of the neutral overrides reads 1500), unless
        someone else already changed the mode."""
        s = self.session
        if self.found_mode is None or s.heartbeat is None or s.heartbeat.custom_mode != self.flight_mode:
            return []
        self.guided.hold()
        if s.set_mode(MANUAL):
            return [f"{mode_name(self.flight_mode)} left for MANUAL (confirmed by HEARTBEAT)"]
        self.unconfirmed.append("leave GUIDED")
        return [f"{mode_name(self.flight_mode)} NOT left (no confirmation)"]

    def _restore_mode(self) -> list[str]:
        """After the disarm: the mode the run found (MANUAL if that was GUIDED)."""
        s = self.session
        mode = MANUAL if self.found_mode in (None, self.flight_mode) else self.found_mode
        if self.found_mode is None or s.heartbeat is None or s.heartbeat.custom_mode == mode:
            return []
        if s.set_mode(mode):
            return [f"mode back to {mode_name(mode)} (confirmed by HEARTBEAT)"]
        self.unconfirmed.append(f"mode {mode_name(mode)}")
        return [f"mode NOT back to {mode_name(mode)} (no confirmation)"]

    def _prove_overrides(self) -> None:
        """ArduSub takes overrides only from its GCS sysid, and none with RC_OVERRIDE_TIME = 0: before any output
        is switched, hold a probe value inside every T200 dead band (no thrust, whatever drives the outputs) until
        RC_CHANNELS shows it on all eight channels."""
        s = self.session
        s.send_override([OVERRIDE_PROBE] * CHANNELS)
        deadline = time.monotonic() + s.clock.wall_seconds(PROBE_WAIT) + 0.5
        while time.monotonic() < deadline:
            self._interrupt()
            for msg, _ in s.poll(0.02):
                self._track(msg)
                if msg.get_type() == "RC_CHANNELS" and all(
                        getattr(msg, f"chan{i}_raw") == OVERRIDE_PROBE for i in range(1, CHANNELS + 1)):
                    self.say("RC overrides accepted by the vehicle (RC_CHANNELS echoes them)")
                    return
        raise Abort(f"the vehicle does not apply our RC overrides (RC_CHANNELS never showed {OVERRIDE_PROBE} us): "
                    f"check that sysid {s.sysid} is its GCS sysid (MAV_GCS_SYSID / SYSID_MYGCS) and that "
                    "RC_OVERRIDE_TIME is not 0")

    # -- the loop --------------------------------------------------------------------------------------------

    def _fly(self) -> None:
        o = self.options
        stale_after = o.stale_periods * self.period
        watch_from = self.session.clock.now()        # the watchdog counts from the loop's start at the earliest
        turned = time.perf_counter()
        while True:
            self._interrupt()
            turned = self._notice_stall(turned)
            state = self._pump(min(self.session.clock.wall_seconds(self.period), 0.02))
            if state is not None:
                if self._tick(state):
                    return
                continue
            seen = self.last_state.t if self.last_state is not None else watch_from
            age = self.session.clock.now() - max(seen, watch_from)
            if age > o.link_timeout and (state := self._pump(0.0)) is not None:
                self._tick(state)           # it was this process that stalled, not the link
                continue
            if age > o.link_timeout:
                raise LinkLost(f"link lost: no telemetry from the vehicle for {age:.1f} s of vehicle time "
                               f"(limit {o.link_timeout:g} s)")
            if age > stale_after and not self.stale:
                self.stale = True
                self.stale_episodes += 1
                if not o.dry_run:
                    self._send_neutral()
                    if self.guided is not None:
                        self.guided.hold()
                if self.stale_episodes <= STALE_REPORTS:
                    more = " (further episodes are counted in the final report)" \
                        if self.stale_episodes == STALE_REPORTS else ""
                    self.say(f"telemetry stale ({age * 1e3:.0f} ms): neutral on all thrusters until it returns"
                             + more, "warning")

    def _notice_stall(self, last: float) -> float:
        """A turn of the loop much later than the last one: this process stalled (a busy computer, SIGSTOP), the
        thrusters holding its last command meanwhile. Noted, the next commands eased in from the one held
        (`RESUME_RAMP`), and a run stalled again and again for most of the last STARVED_WINDOW s stops: it cannot
        control the vehicle.
        Returns this turn's wall time."""
        now = time.perf_counter()
        gap = now - last
        if gap <= max(STALL, self.session.clock.wall_seconds(STALL_PERIODS * self.period)):
            return now
        self.stalls += 1
        self._resumed = self.session.clock.now()
        self._stalled.append((now, gap))
        while self._stalled and self._stalled[0][0] < now - STARVED_WINDOW:
            self._stalled.popleft()
        if self.stalls <= STALE_REPORTS:
            self.say(f"this process stalled for {gap * 1e3:.0f} ms (the thrusters held its last command): easing "
                     "back in" + (" (further stalls are counted in the final report)" if self.stalls == STALE_REPORTS
                                  else ""), "warning")
        share = sum(min(g, STARVED_WINDOW) for _, g in self._stalled) / STARVED_WINDOW
        if len(self._stalled) > 1 and share > STARVED_SHARE and not self.options.dry_run:
            raise Abort(f"this computer is starving the control loop: stalled {share:.0%} of the last "
                        f"{STARVED_WINDOW:g} s ({len(self._stalled)} stalls); the thrusters hold stale commands "
                        "meanwhile (run it with --realtime, or on a less busy computer)")
        return now

    def _pump(self, timeout: float) -> State | None:
        """Read what arrived; returns the newest complete state, if any."""
        received = None
        for msg, wall in self.session.poll(timeout):
            if self._track(msg):
                received = wall
        if received is None:
            return None
        self.last_state = self.decoder.state(received)
        return self.last_state

    def _pump_for(self, vehicle_seconds: float) -> None:
        end = time.monotonic() + self.session.clock.wall_seconds(vehicle_seconds)
        while time.monotonic() < end:
            self._interrupt()
            self._pump(0.01)

    def _track(self, msg) -> bool:
        """Decode one message (True if it completes a state); notice the vehicle's texts and its disarming."""
        kind = msg.get_type()
        if kind == "STATUSTEXT":
            self.say(f"vehicle: {msg.text}", "warning" if msg.severity <= mavlink.MAV_SEVERITY_WARNING else "info")
        elif kind == "RC_CHANNELS" and self._rc_seen is not None:
            self._rc_seen.append([getattr(msg, f"chan{i}_raw") for i in range(1, CHANNELS + 1)])
        if self.flying_since is not None and not self.stopping:
            self._watch(msg, kind)
        return self.decoder.update(msg)

    def _watch(self, msg, kind: str) -> None:
        """While the vehicle is ours: is anyone else driving it? (PilotTakeover; Abort if it was disarmed.)"""
        s = self.session
        now = s.clock.now()
        if kind == "HEARTBEAT":
            if not msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED:
                raise Abort("the vehicle was disarmed during the run (a failsafe, or another station)")
            if msg.custom_mode != self.flight_mode:
                mode = mode_name(msg.custom_mode)
                raise PilotTakeover(f"the vehicle's mode was changed to {mode} by someone else", now)
        elif kind == "RC_CHANNELS" and s.echo.report([getattr(msg, f"chan{i}_raw") for i in range(1, CHANNELS + 1)]):
            raise PilotTakeover("the vehicle's RC input is not what this run sends (RC_CHANNELS "
                                f"{[getattr(msg, f'chan{i}_raw') for i in range(1, CHANNELS + 1)]}): another station is "
                                "writing it", now)
        stations = s.stations
        if moving := stations.pilots_moving(self.flying_since):
            raise PilotTakeover(f"pilot takeover: {moving[0].describe()}", moving[0].deflected_at, moving[0])
        if overriding := stations.overriding(self.flying_since):
            raise PilotTakeover(f"another station took over the thrusters: {overriding[0].describe()}",
                                overriding[0].last_drive, overriding[0])
        if self.saved_gcs is None and (joysticks := stations.joysticks(self.flying_since, s.sysid)):
            raise PilotTakeover(f"a pilot station on our GCS sysid started sending MANUAL_CONTROL, which ArduSub "
                                f"writes over our thrusters: {joysticks[0].describe()}", joysticks[0].last_drive,
                                joysticks[0])

    def _mission_time(self, t: float) -> float:
        """Vehicle s since the mission proper started (negative during the lead-in)."""
        if self.t_start is None:
            return 0.0
        lead = self.lead_in.duration if self.lead_in is not None else 0.0
        return t - self.t_start - lead

    def _tick(self, state: State) -> bool:
        """One control tick; True when the mission is complete."""
        o = self.options
        if self.t_start is None:
            self.t_start = state.t
            self.lead_in = approach(state.eta, self.mission.start_pose, o.approach_speed)
            if self.lead_in is not None:
                self.say(f"lead-in to the mission's start pose: {self.lead_in.duration:.1f} s")
            self._prev_t = state.t - self.period
        if self.stale:
            self.stale = False
            if self.stale_episodes <= STALE_REPORTS:
                self.say("telemetry back: control resumed")
        t = self._mission_time(state.t)
        if t >= 0 and not self.announced and not o.dry_run:
            self.announced = True
            self.session.announce(mission_start_text(state.t - t))
        reference = self._reference(t)
        dt = min(max(state.t - self._prev_t, 0.0), o.stale_periods * self.period)
        self._prev_t = state.t
        horizon = 0.0
        if self.guided is not None:
            out, thrusts = self.guided.output, np.full(CHANNELS, np.nan)
            pwm = self.decoder.servo[:CHANNELS] if self.decoder.servo is not None else np.full(CHANNELS, np.nan)
            self._check_limits(state, reference)
            self.guided.tick(state.t, reference, send=not o.dry_run)
        else:
            eta, nu, t_act = state.eta, state.nu, self.session.clock.now() + self.session.round_trip.seconds
            if self.predictor is not None:
                self.predictor.observe(state.t, state.eta, state.nu)
                eta, nu = self.predictor.predicted(state.t, state.eta, state.nu, t_act)
                horizon = t_act - state.t if eta is not state.eta else 0.0
            out = self.controller.step(eta, nu, self._reference(t + horizon) if horizon else reference, dt)
            tau = self._eased(out.tau)
            if self.decoder.voltage is not None:
                self.actuation.set_voltage(self.decoder.voltage)
            thrusts, pwm, _ = self.actuation.command(tau)
            self._check_limits(state, reference)
            if not o.dry_run:
                self._send_outputs(pwm)
            self._commanded(t_act, self.actuation.allocator.matrix @ thrusts)
        latency = time.perf_counter() - state.received
        age = self.session.clock.now() - state.t
        self._count_tick(state.t, latency, horizon)
        if t >= 0:
            self._log.append(t=t, eta=state.eta, eta_d=reference[:6], tau=out.tau, tau_hat=out.tau_hat)
        record = TickRecord(t=t, vehicle_time=state.t, eta=state.eta, nu=state.nu, reference=reference, tau=out.tau,
                            tau_hat=out.tau_hat, s=out.s, gamma=out.gamma, thrusts=thrusts, pwm=pwm, progress=self.mission.progress(t),
                            telemetry_age=age, latency=latency, control_rate=len(self._ticks),
                            battery_voltage=self.actuation.voltage, horizon=horizon,
                            true_disturbance=self.true_disturbance)
        for sink in self.sinks:
            sink.log_tick(record)
        return t >= self.mission.duration

    def _reference(self, t: float) -> np.ndarray:
        """The reference (18,) at mission time t: the lead-in's before 0."""
        return self.mission.reference(t) if t >= 0 else self.lead_in.reference(t + self.lead_in.duration)

    def _send_outputs(self, pwm: np.ndarray) -> None:
        """The tick's eight PWMs: ArduSub's motor test, or RC overrides for the outputs on RCIN passthrough."""
        if self.options.output == MOTOR_TEST:
            self.session.send_motor_test(pwm)
            self.last_command = self.session.motor_test
        else:
            self.session.send_override(pwm)
            self.last_command = self.session.override

    def _eased(self, tau: np.ndarray) -> np.ndarray:
        """The law's wrench, eased in from the one held during a stall over RESUME_RAMP vehicle s after it: the
        first command after a stall is not the whole correction of an error that grew while nothing was sent."""
        if self._resumed is None:
            return tau
        share = (self.session.clock.now() - self._resumed) / RESUME_RAMP
        if share >= 1.0:
            self._resumed = None
            return tau
        return self._held_tau + max(share, 0.0) * (tau - self._held_tau)

    def _commanded(self, t_act: float, wrench: np.ndarray) -> None:
        """The wrench just sent (zero for neutral), acting from vehicle time t_act: held for the next stall and
        known to the prediction."""
        self._held_tau = wrench
        if self.predictor is not None:
            self.predictor.commanded(t_act, wrench)

    def _count_tick(self, t: float, latency: float, horizon: float) -> None:
        self._ticks.append(t)
        while self._ticks and self._ticks[0] <= t - 1.0:
            self._ticks.popleft()
        self._loop.append(tick_time=t, latency_ms=latency * 1e3, horizon_ms=horizon * 1e3)

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
        servo = self.decoder.servo
        if lim.max_thrust is not None and servo is not None and self.actuation.beyond_cap(servo).any():
            crossed.append(f"thruster outputs {servo.astype(int).tolist()} us (SERVO_OUTPUT_RAW) beyond the "
                           f"{self.actuation.describe_range()} that max_thrust {lim.max_thrust:g} N allows")
        if not crossed:
            return
        if not self.options.dry_run:
            raise Abort("limit crossed: " + "; ".join(crossed))
        for text in crossed:
            kind = text.split(" ")[0]
            if kind not in self.warned:
                self.warned.add(kind)
                self.say(f"dry run: would abort here: {text}", "warning")

    # -- stop ------------------------------------------------------------------------------------------------

    def _send_neutral(self) -> None:
        self.session.send_override([NEUTRAL] * CHANNELS)
        if self.session.motor_test is not None:
            self.session.send_motor_test([NEUTRAL] * CHANNELS)
        self.actuation.reset()
        self._commanded(self.session.clock.now() + self.session.round_trip.seconds, np.zeros(6))
        self.touched = True

    def _safe_stop(self, reason: str) -> list[str]:
        """Neutral, release, disarm, restore; returns what was done, one line each."""
        s = self.session
        report = [f"stopping: {reason}"]
        if s.rejections is not None and s.rejections.count:
            report.append(s.rejections.summary())
        if self.stalls:
            report.append(f"this process stalled {self.stalls} time(s) (over {STALL * 1e3:.0f} ms between turns of "
                          "its loop): the thrusters held its last command meanwhile")
        if self.stale_episodes:
            report.append(f"watchdog: telemetry went stale {self.stale_episodes} time(s) (older than "
                          f"{self.options.stale_periods:g} control periods); neutral was sent each time")
        if s.vehicle is None:
            return self._finish(report + ["no ArduSub vehicle was taken over: nothing was sent that changes one"])
        if not self.touched and not self.changed_functions and not self.armed_by_us and self.saved_gcs is None:
            if not self.options.dry_run:
                report.append("nothing had been changed on the vehicle")
            else:
                report.append("dry run: no parameter changed, nothing armed, no override sent")
            report += self._restore_streams(alive=self._answering())
            return self._finish(report)
        def attempt(label: str, action):
            try:
                return action()
            except Exception as exc:   # noqa: BLE001 -- one failed step must not skip the next ones
                report.append(f"{label} FAILED: {exc!r}")
                return None

        if self.guided is not None:
            report += attempt("leave GUIDED", self._leave_guided) or []
        confirm = HANDOVER_CONFIRM if self.takeover is not None else SAFE_STOP_CONFIRM
        neutral_confirmed = bool(attempt("neutral", lambda: self._neutral(confirm)))
        alive = neutral_confirmed or self._answering()
        retry_until = time.monotonic() + LOST_LINK_RETRY
        # A glitch, a busy vehicle or a link coming back: keep sending neutral until it shows (handing over, the
        # pilot's joystick may rule the outputs: once is enough while the vehicle answers).
        while not neutral_confirmed and (not alive or self.takeover is None) and time.monotonic() < retry_until:
            neutral_confirmed = bool(attempt("neutral", lambda: self._neutral(confirm)))
            alive = neutral_confirmed or self._answering()
        report.append("neutral 1500 us on channels 1-8: sent, "
                      + ("confirmed by SERVO_OUTPUT_RAW" if neutral_confirmed else "NOT confirmed"))
        if not neutral_confirmed and (self.takeover is None or not alive):   # handing over, the pilot's RC rules
            self.unconfirmed.append("neutral")
        if not alive:
            # No release: arriving together with the neutral, it would cancel it (both land before the vehicle
            # next reads its RC input), leaving the flight command in place. Neutral stays the last word.
            attempt("disarm", lambda: s.fire(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0.0))
            report.append("disarm: sent, no answer")
            pending = self.changed_functions + ([self.saved_gcs[0]] if self.saved_gcs is not None else [])
            self.unconfirmed += (["disarm"] if self.armed_by_us else []) + (
                ["restore " + ", ".join(pending)] if pending else [])
            last = self.last_command or [NEUTRAL] * CHANNELS
            if s.motor_test is not None:
                s.end_motor_test()
                report.append(
                    "THE LINK IS GONE: the vehicle did not answer. Its thrusters were driven by ArduSub's motor test, "
                    f"which it ends {MOTOR_TEST_TIMEOUT:g} s of vehicle time after the last command reached it: "
                    f"outputs neutral, vehicle disarmed (the last flight command sent was {last}; neutral was sent "
                    "after it, unconfirmed)."
                    + (f" Set {self.saved_gcs[0]} back to {self.saved_gcs[1]} when the link is back."
                       if self.saved_gcs is not None else ""))
                return self._finish(report)
            report.append(
                "THE LINK IS GONE: the vehicle did not answer. Its thrusters HOLD THEIR LAST COMMAND: RCIN "
                "passthrough keeps the last PWM that reached it (the last flight command sent was "
                f"{last}; neutral was sent after it, unconfirmed), arming does not gate it and ArduSub's "
                "failsafes do not reset channels 7-8."
                + (" SERVOn_FUNCTION were NOT restored (still RCIN passthrough): restore "
                   + ", ".join(f"{n}={int(self.saved_functions[n][0])}" for n in self.changed_functions)
                   + " as soon as the link is back (the next `rov-mav run` does it when it ends)."
                   if self.changed_functions else ""))
            return self._finish(report)
        if not neutral_confirmed and self.takeover is None:
            self._pump_for(NEUTRAL_HOLD)           # give the vehicle time to apply it before letting go
        if attempt("release", lambda: s.release_overrides() or True):
            report.append("RC overrides on channels 1-8 released")
        else:
            self.unconfirmed.append("release")
        if self.armed_by_us and self.takeover is None:
            if attempt("disarm", lambda: s.arm(False)):
                report.append("disarmed (confirmed by HEARTBEAT)")
            else:
                report.append("disarm NOT confirmed")
                self.unconfirmed.append("disarm")
        if s.motor_test is not None:
            s.end_motor_test()
            report.append(f"motor test no longer sent: ArduSub ends it {MOTOR_TEST_TIMEOUT:g} s later (and disarms)")
        if self.guided is not None and self.takeover is None:
            report += attempt("restore mode", self._restore_mode) or []
        # The motors first, then the GCS sysid: a pilot's joystick must never reach an output on passthrough.
        restore = {name: self.saved_functions[name] for name in self.changed_functions}
        if self.saved_gcs is not None:
            name, value, ptype = self.saved_gcs
            report += self._restore(attempt, restore) + self._restore(attempt, {name: (float(value), ptype)})
        else:
            report += self._restore(attempt, restore)
        if self.takeover is not None:
            report.append(self._handover_note())
        streams = attempt("message rates", lambda: self._restore_streams(alive=True))
        if streams is None:
            self.unconfirmed.append("reset message rates")
        return self._finish(report + (streams or []))

    def _restore(self, attempt, values: dict[str, tuple[float, int]]) -> list[str]:
        """Set the saved parameters back, all at once; one line for the confirmed, one for the rest."""
        if not values:
            return []
        failed = attempt("restore " + ", ".join(values), lambda: self.session.set_params(values))
        failed = list(values) if failed is None else failed
        lines = []
        if restored := [f"{n}={int(v)}" for n, (v, _) in values.items() if n not in failed]:
            lines.append("restored " + ", ".join(restored) + " (confirmed by PARAM_VALUE)")
        if failed:
            lines.append("NOT restored (no confirmation): " + ", ".join(f"{n}={int(values[n][0])}" for n in failed))
            self.unconfirmed.append("restore " + ", ".join(failed))
        return lines

    def _handover_note(self) -> str:
        s = self.session
        mode = mode_name(s.heartbeat.custom_mode)
        state = "armed" if s.armed else "NOT armed"
        took = s.clock.now() - self.takeover.t_detected
        gcs = self.saved_gcs[1] if self.saved_gcs is not None else s.sysid
        station = self.takeover.station
        follows = "ArduSub's mixer follows the GCS's joystick" if station is None or station.sysid == gcs else (
            f"ArduSub ignores the joystick of sysid {station.sysid} until its GCS sysid ({gcs}) is set to it")
        if self.options.output == MOTOR_TEST:
            follows = (f"ArduSub ends the motor test {MOTOR_TEST_TIMEOUT:g} s after our last command and disarms: "
                       f"arm it again to drive; then {follows}")
        return (f"handed over {took:.2f} s of vehicle time after it was seen: {state} in {mode}, thrusters on their "
                f"motors ({follows}), overrides released")

    def _neutral(self, confirm: float = SAFE_STOP_CONFIRM) -> bool:
        """Send neutral and wait up to `confirm` vehicle s for SERVO_OUTPUT_RAW showing 1500 on SERVO1..8."""
        self._send_neutral()
        self.decoder.servo = None
        slack = 0.3 if self.takeover is None else 0.0      # a late report is worth waiting for, unless handing over
        deadline = time.monotonic() + self.session.clock.wall_seconds(confirm) + slack
        while time.monotonic() < deadline:
            self._pump(0.01)
            if self.decoder.servo is not None:
                if np.all(np.abs(self.decoder.servo - NEUTRAL) <= 1):
                    return True
                self.decoder.servo = None          # still the old outputs: wait for the next report
        return False

    def _answering(self) -> bool:
        """Has the vehicle sent anything recently (within the link timeout)?"""
        clock = self.session.clock
        if not clock.started:
            return False
        self._pump(0.05)
        return clock.now() - clock.last_vehicle <= self.options.link_timeout and \
            time.perf_counter() - clock.last_wall <= clock.wall_seconds(self.options.link_timeout)

    def _restore_streams(self, alive: bool) -> list[str]:
        if not self.streams_set or not alive:
            return []
        ok = all(self.session.command(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, msg_id, 0) ==
                 mavlink.MAV_RESULT_ACCEPTED for msg_id in self.streams_set)
        if not ok:
            self.unconfirmed.append("reset message rates")
        return ["message rates back to the vehicle's defaults" if ok else "message rates NOT all reset"]

    def _finish(self, report: list[str]) -> list[str]:
        if self.unconfirmed:
            report.append(f"safe stop NOT complete: {'; '.join(self.unconfirmed)} not confirmed by the vehicle")
        for line in report:
            self.say(line, "warning" if "NOT" in line or "GONE" in line else "info")
        return report

    def _result(self, code: int, reason: str, completed: bool, report: list[str]) -> RunResult:
        log = self._log
        return RunResult(
            code=code, reason=reason, completed=completed, t=log.column("t"), eta=log.column("eta"),
            eta_d=log.column("eta_d"), tau=log.column("tau"), tau_hat=log.column("tau_hat"),
            latency_ms=self._loop.column("latency_ms"), tick_times=self._loop.column("tick_time"),
            horizon_ms=self._loop.column("horizon_ms"),
            round_trip_ms=self.session.round_trip.seconds * 1e3 if self.session.round_trip.samples else float("nan"),
            stalls=self.stalls, report=report)


_MISSING_HELP = {
    "LOCAL_POSITION_NED": "the vehicle's estimator has no position source (ArduSub sends it only once its EKF has "
                          "an origin and position aiding: a DVL or similar on a real BlueROV2; about 45 s after "
                          "boot on SITL)",
    "ATTITUDE": "the vehicle sends no attitude: check the link and the vehicle's stream rates",
}
_MISSING_HELP["ATTITUDE and LOCAL_POSITION_NED"] = _MISSING_HELP["ATTITUDE"]
