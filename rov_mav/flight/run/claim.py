"""Claiming the vehicle, before anything drives it: identify it (ArduSub on a sub), refuse one whose frame or motor
outputs are not what the vehicle file describes (`vehicle_frame`), watch the link for a few seconds sending nothing
but reads and refuse a vehicle that is someone else's (`stations.judge`), then take the GCS role if
a pilot's joystick shares the GCS sysid, make abandoned passthrough outputs neutral, ask for the telemetry the law
needs and check its rate. Every change is written into the run's `VehicleChanges` as it is made."""

from __future__ import annotations

import time

import numpy as np

from rov_mav.flight.session.link import CHANNELS, mavlink
from rov_mav.flight.run.run_io import RunIO
from rov_mav.flight.run.run_options import Abort
from rov_mav.flight.session.stations import Sighting, Verdict, judge
from rov_mav.flight.session.stream_rate import measure, too_slow
from rov_mav.flight.session.vehicle_frame import OUTPUTS, banner_frame, find_motors, frame_refusal
from rov_mav.model.frames import MOTOR_FUNCTION_BASE, frame_of
from rov_mav.model.vehicle import Vehicle

SIDE_RATES = {"SYS_STATUS": 2.0, "EKF_STATUS_REPORT": 5.0,   # vehicle Hz; a lost position stops the run at once
              "SERVO_OUTPUT_RAW": 10.0, "RC_CHANNELS": 5.0}      # a pilot's joystick interleaved with our overrides
# shows in some of these (`OverrideEcho`): SERVO_OUTPUT_RAW goes up to OUTPUT_WATCH Hz of vehicle time, as long as
# that is at most OUTPUT_WATCH_WALL a wall second (a simulator sped up 5-10x: more cost the loop its rate, measured)
OUTPUT_WATCH, OUTPUT_WATCH_WALL = 50.0, 50.0
RATE_WINDOW = 3.0                # vehicle s of telemetry measured before arming (enough to see through 30 % loss)
OBSERVE = 3.0                    # vehicle s of watching the link, sending nothing, before deciding to take it
OBSERVE_POLL = 0.25              # vehicle s between one-shot requests for RC_CHANNELS and SERVO_OUTPUT_RAW then
ROLE_SYSIDS = range(254, 200, -1)   # sysids to take the GCS role with, when a pilot's joystick holds the GCS sysid
DRY_RUN_SYSID = 254              # a dry run's own sysid: anything but the vehicle's GCS sysid
GCS_SYSID_HIGH = "MAV_GCS_SYSID_HI"   # ArduSub 4.7: the top of a range of GCS sysids (0: none)
PROGRESS_EVERY = 5.0             # wall s between "still waiting" messages
BANNER_WAIT = 3.0                # vehicle s for the "Frame:" line of the banner, where FRAME_CONFIG was not read
THRUSTERS, MOTORS, FRAME = "thrusters", "motors", "frame"   # what a route needs of the vehicle (`VehicleClaim`)


class VehicleClaim:
    """`claim()`: the vehicle identified, held to `vehicle` (the vehicle file), judged free, and ready to be taken
    (the GCS role, abandoned outputs neutral, the state streaming at the control rate); Abort if it must not be.
    `set_directions(signs)` receives the vehicle's MOT_1..8_DIRECTION. `needs`: what the route needs of the vehicle:
    THRUSTERS (RC passthrough: the frame, each motor on one output, no other output passing the thruster channels
    on), MOTORS (the motor test: the frame and each motor on one output) or FRAME (GUIDED: ArduSub's own mixer)."""

    def __init__(self, io: RunIO, set_directions, vehicle: Vehicle, needs: str = THRUSTERS):
        self.io = io
        self.set_directions = set_directions
        self.vehicle = vehicle
        self.needs = needs
        self.speed = 1.0            # vehicle s per wall s over the observation (a simulator's speedup)

    def claim(self) -> None:
        io, s, o, changes = self.io, self.io.session, self.io.options, self.io.changes
        vehicle = s.connect(o.heartbeat_timeout)
        io.say(f"vehicle: ArduSub submarine, sysid {vehicle.sysid}, on {s.target}")
        since = s.clock.now()
        self._hold_to_vehicle_file()
        passthrough = [] if o.dry_run else self._read_outputs()
        gcs = s.gcs_sysid()
        verdict = judge(self._observe(since, passthrough), s.stations, o.force)
        for station in s.stations.stations.values():
            io.say(f"also on the link: {station.describe()}")
        if verdict.refusal is not None:
            raise Abort(f"refusing to take the vehicle: {verdict.refusal}. Nothing was sent to it (--force to take "
                        "it over anyway)")
        # From here on the vehicle is ours: free, or left by a run that died.
        self._use_gcs_sysid(gcs, verdict)
        s.start_heartbeats()
        s.timesync = True            # the round trip, for the prediction and the summary
        if verdict.abandoned:
            self._take_abandoned_outputs(verdict.abandoned)
        watch = min(OUTPUT_WATCH, max(SIDE_RATES["SERVO_OUTPUT_RAW"], OUTPUT_WATCH_WALL / self.speed))
        for name in ("ATTITUDE", "LOCAL_POSITION_NED", *SIDE_RATES):
            msg_id = getattr(mavlink, f"MAVLINK_MSG_ID_{name}")
            hz = watch if name == "SERVO_OUTPUT_RAW" else SIDE_RATES.get(name, o.rate)
            if s.set_message_interval(msg_id, hz):
                changes.streams.append(msg_id)
            elif name in ("ATTITUDE", "LOCAL_POSITION_NED"):
                raise Abort(f"the vehicle refused SET_MESSAGE_INTERVAL for {name} at {hz:g} Hz")
        self._ask_origin()
        self._wait_for_state()
        self._check_rates()

    def _ask_origin(self) -> None:
        """The EKF origin LOCAL_POSITION_NED is relative to (GPS_GLOBAL_ORIGIN, or HOME_POSITION where the vehicle
        has none to give: ArduPilot sends them on MAV_CMD_REQUEST_MESSAGE), so that a simulator's true position
        (SIM_STATE, `flight.session.truth`) can be set against the estimate. A real vehicle's answer changes nothing."""
        s = self.io.session
        for name in ("GPS_GLOBAL_ORIGIN", "HOME_POSITION"):
            if s.command(mavlink.MAV_CMD_REQUEST_MESSAGE, getattr(mavlink, f"MAVLINK_MSG_ID_{name}")) == \
                    mavlink.MAV_RESULT_ACCEPTED:
                return

    def _observe(self, since: float, passthrough: list[str]) -> Sighting:
        """Watch the link for OBSERVE vehicle s, sending nothing but one-shot requests for RC_CHANNELS and
        SERVO_OUTPUT_RAW (no stream rate is changed): who else is there, and is the RC input steady?"""
        io, s = self.io, self.io.session
        io.rc_seen = []
        wall_end = time.monotonic() + s.clock.wall_seconds(OBSERVE) + 1.0
        start, next_poll = None, 0.0
        while time.monotonic() < wall_end:
            io.interrupt()
            now = s.clock.now()
            if start is None and s.clock.started:
                start, wall_start = now, time.monotonic()
            if start is not None and now - start >= OBSERVE:
                self.speed = (now - start) / max(time.monotonic() - wall_start, 1e-3)
                break
            if time.monotonic() >= next_poll:
                next_poll = time.monotonic() + s.clock.wall_seconds(OBSERVE_POLL)
                s.request_message(mavlink.MAVLINK_MSG_ID_RC_CHANNELS)
                s.request_message(mavlink.MAVLINK_MSG_ID_SERVO_OUTPUT_RAW)
            io.pump(0.02)
        rc, io.rc_seen = io.rc_seen, None
        return Sighting(since=since, armed=s.armed, passthrough=passthrough, rc=rc)

    def _hold_to_vehicle_file(self) -> None:
        """Refuse, changing nothing, a vehicle whose frame is not the vehicle file's or (as the route needs) whose
        motors are not each on one output; else note where they are (`io.motors`) and keep their outputs' functions
        to restore."""
        io, s, expected = self.io, self.io.session, self.vehicle.frame
        names = [f"SERVO{n}_FUNCTION" for n in range(1, OUTPUTS + 1)]
        found = s.get_params(["FRAME_CONFIG", *names])
        frame = frame_of(int(found["FRAME_CONFIG"][0])) if "FRAME_CONFIG" in found else self._banner_frame()
        refusal = frame_refusal(frame, expected, self.vehicle.name)
        if refusal is not None:
            raise _refusal(refusal)
        said = f"frame: {frame.describe()}" + ("" if "FRAME_CONFIG" in found else ' (from its "Frame:" banner)')
        if missing := [n for n in names if n not in found]:
            if self.needs == FRAME:
                io.say(f"{said}: ArduSub's own mixer drives its motors")
                return
            raise Abort(f"could not read {', '.join(missing)} from the vehicle: nothing was changed on it")
        functions = {n: int(found[name][0]) for n, name in enumerate(names, 1)}
        motors = find_motors(functions, expected, self.vehicle.name, passthrough=self.needs == THRUSTERS)
        if isinstance(motors, str):
            if self.needs != FRAME:
                raise _refusal(motors)
            io.say(f"{said}: ArduSub's own mixer drives its motors; but {motors}", "warning")
            return
        io.motors = motors
        io.changes.saved_functions = {name: found[name] for name in motors.names()}
        io.say(f"{said}, {motors.describe()}: the vehicle the vehicle file describes"
               + (" (a dry run reads them only)" if io.options.dry_run else ""))

    def _banner_frame(self):
        """The frame the vehicle's "Frame:" banner line names (MAV_CMD_DO_SEND_BANNER), for a vehicle that did not
        give FRAME_CONFIG; Abort when it says none."""
        s = self.io.session
        before = s.texts_seen
        s.command(mavlink.MAV_CMD_DO_SEND_BANNER)
        s.wait(lambda m: m.get_type() == "STATUSTEXT" and m.text.startswith("Frame:"),
               s.clock.wall_seconds(BANNER_WAIT))
        lines = [text for text in s.texts_after(before) if text.startswith("Frame:")]
        frame = banner_frame(lines[-1], self.vehicle.frame) if lines else None
        if frame is None:
            raise _refusal("it gave neither FRAME_CONFIG nor a known \"Frame:\" line ("
                           + (repr(lines[-1]) if lines else "no banner") + ")")
        return frame

    def _read_outputs(self) -> list[str]:
        """Learn MOT_1..8_DIRECTION; returns the motors' outputs found on RCIN passthrough (a run that lost its link)
        and saves their motor function to restore."""
        io, s, changes = self.io, self.io.session, self.io.changes
        directions = s.get_params([f"MOT_{n}_DIRECTION" for n in range(1, CHANNELS + 1)])
        signs = [directions.get(f"MOT_{n}_DIRECTION", (1.0, 0))[0] for n in range(1, CHANNELS + 1)]
        self.set_directions(np.array(signs))
        reversed_ = [n for n, sign in enumerate(signs, 1) if sign < 0]
        if reversed_:
            io.say(f"MOT_n_DIRECTION = -1 on thruster(s) {reversed_}: passthrough and the motor test bypass it, so "
                   "their PWM is mirrored about 1500")
        stale = []
        for k, output in enumerate(io.motors.outputs, 1):
            if output in io.motors.stale:
                name = io.motors.name(k)
                changes.saved_functions[name] = (float(MOTOR_FUNCTION_BASE + k), changes.saved_functions[name][1])
                stale.append(name)
        return stale

    def _take_abandoned_outputs(self, stale: list[str]) -> None:
        """Outputs already on RCIN passthrough (a run that lost its link?) still drive their thrusters with the
        last PWM: send neutral, and restore them to their motors when this run ends, whatever happens."""
        io = self.io
        io.say(f"{', '.join(stale)} on RCIN passthrough with the vehicle disarmed and no station driving them for "
               f"{OBSERVE:g} s: taken as abandoned (a run that lost its link?); sending neutral; they will be "
               "restored to their motors when this run ends", "warning")
        io.session.override_rate = io.options.rate
        io.changes.functions += stale
        if not io.neutral_confirmed():
            raise Abort("outputs left on RCIN passthrough and the vehicle does not confirm neutral")

    def _use_gcs_sysid(self, found: tuple[str, int, int] | None, verdict: Verdict) -> None:
        """Speak as the vehicle's GCS sysid (ArduSub takes RC overrides only from it). When a pilot station's
        joystick shares that sysid, ArduSub would write it over our thrusters: take the GCS role for the run with a
        sysid of our own (the parameter is restored on every exit), so ArduSub ignores the resting joystick while we
        watch it."""
        io, s, o = self.io, self.io.session, self.io.options
        if found is None:
            s.use_sysid(o.sysid or s.sysid)
            io.say(f"the vehicle did not report MAV_GCS_SYSID or SYSID_MYGCS: speaking as sysid {s.sysid}",
                   "warning")
            return
        name, value, ptype = found
        if name == "MAV_GCS_SYSID":                 # 4.7 and later
            self._single_gcs_sysid(value)
        if o.dry_run:
            # Heartbeats from the GCS sysid would hide a lost link from the pilot's own ground station (and ArduSub
            # would count them for its GCS failsafe): a dry run, which sends no override, speaks as another sysid.
            s.use_sysid(DRY_RUN_SYSID if value != DRY_RUN_SYSID else DRY_RUN_SYSID - 1)
            io.say(f"dry run: speaking as sysid {s.sysid}, not the vehicle's GCS sysid ({name} = {value})")
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
            io.say(f"speaking as GCS sysid {s.sysid} ({name} = {value})")
            return
        if not s.set_param(name, own, ptype):
            raise Abort(f"the vehicle did not confirm {name} = {own}")
        io.changes.gcs = (name, value, ptype)
        s.use_sysid(own)
        why = (f": {', '.join(p.describe() for p in pilots)} is ignored by ArduSub until the run ends or hands the "
               "vehicle to it" if pilots else "")
        io.say(f"took the GCS role for this run: speaking as sysid {own}, {name} = {own} (was {value}; restored "
               f"when the run ends){why}")

    def _single_gcs_sysid(self, low: int) -> None:
        """ArduSub 4.7's MAV_GCS_SYSID_HI above MAV_GCS_SYSID makes every sysid between them a GCS
        (`GCS::sysid_is_gcs`): any station in the range could drive the thrusters through our passthrough unnoticed.
        The run sets it to 0 (one GCS sysid) and restores it on every exit, after the outputs are back on their
        motors; a dry run only says so."""
        io, s = self.io, self.io.session
        found = s.get_params([GCS_SYSID_HIGH])
        if GCS_SYSID_HIGH not in found or int(found[GCS_SYSID_HIGH][0]) <= low:
            return
        high, ptype = int(found[GCS_SYSID_HIGH][0]), found[GCS_SYSID_HIGH][1]
        if io.options.dry_run:
            io.say(f"{GCS_SYSID_HIGH} = {high}: every sysid from {low} to {high} is a GCS the vehicle obeys (a run "
                   "sets it to 0 while it flies)", "warning")
            return
        if not s.set_param(GCS_SYSID_HIGH, 0, ptype):
            raise Abort(f"the vehicle did not confirm {GCS_SYSID_HIGH} = 0")
        io.changes.gcs_high = (high, ptype)
        io.say(f"{GCS_SYSID_HIGH} = 0 for this run (was {high}: stations with sysids {low}-{high} could drive the "
               "thrusters; restored when the run ends)")

    def _wait_for_state(self) -> None:
        """Until ATTITUDE and LOCAL_POSITION_NED have both arrived, with progress messages and a timeout."""
        io, timeout = self.io, self.io.options.position_timeout
        start = time.monotonic()
        next_note = start + PROGRESS_EVERY
        while io.decoder.attitude is None or io.decoder.position is None:
            io.interrupt()
            io.pump(0.05)
            now = time.monotonic()
            missing = self._missing_state()
            if now - start > timeout:
                raise Abort(f"no {missing} from the vehicle after {timeout:g} s: "
                            + _MISSING_HELP.get(missing, "check the link"))
            if now >= next_note:
                next_note = now + PROGRESS_EVERY
                io.say(f"waiting for {missing} ({now - start:.0f} s of {timeout:g} s)")

    def _missing_state(self) -> str:
        decoder = self.io.decoder
        names = [n for n, m in (("ATTITUDE", decoder.attitude), ("LOCAL_POSITION_NED", decoder.position))
                 if m is None]
        return " and ".join(names)

    def _check_rates(self) -> None:
        """Measure the state messages' rates over RATE_WINDOW vehicle s: what the vehicle sends, what arrives."""
        io, s = self.io, self.io.session
        stamps: dict[str, list[float]] = {"ATTITUDE": [], "LOCAL_POSITION_NED": []}
        t_first = None
        deadline = time.monotonic() + s.clock.wall_seconds(RATE_WINDOW) * 3 + 2.0
        while time.monotonic() < deadline:
            io.interrupt()
            for msg, _ in s.poll(0.02):
                io.track(msg)
                kind = msg.get_type()
                if kind in stamps:
                    stamps[kind].append(msg.time_boot_ms / 1000.0)
                    t_first = stamps[kind][0] if t_first is None else t_first
            if t_first is not None and s.clock.now() - t_first >= RATE_WINDOW:
                break
        rates = {k: measure(v) for k, v in stamps.items()}
        io.say("telemetry: " + "; ".join(f"{k} {r.describe()}" for k, r in rates.items())
               + f" (asked {io.options.rate:g} Hz of vehicle time)")
        slow = [why for k, r in rates.items() if (why := too_slow(k, r, io.options.rate)) is not None]
        if slow:
            raise Abort("telemetry too slow for the control rate: " + "; ".join(slow))


def _refusal(why: str) -> Abort:
    """The one line a vehicle the vehicle file does not describe is refused with."""
    return Abort(f"refusing to fly this vehicle: {why}. Nothing was changed on it")


_MISSING_HELP = {
    "LOCAL_POSITION_NED": "the vehicle's estimator has no position source (ArduSub sends it only once its EKF has "
                          "an origin and position aiding: a DVL or similar on a real BlueROV2; about 45 s after "
                          "boot on SITL)",
    "ATTITUDE": "the vehicle sends no attitude: check the link and the vehicle's stream rates",
}
_MISSING_HELP["ATTITUDE and LOCAL_POSITION_NED"] = _MISSING_HELP["ATTITUDE"]
