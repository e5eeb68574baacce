"""The safe stop, on every exit path: undo what the run changed on the vehicle (`VehicleChanges`), step by step, each
step confirmed or named as not.

Neutral 1500 on all eight channels (confirmed by SERVO_OUTPUT_RAW; kept up for LOST_LINK_RETRY wall s while the
vehicle is silent), release the overrides, disarm a vehicle this run armed, this output path's own step (the motor
test ended, the mode set back), SERVO1..8_FUNCTION restored before the GCS sysid (a pilot's joystick must never reach
an output still on passthrough), the message rates reset. A step that fails never skips the ones after it. If the
vehicle no longer answers: no release (arriving with the neutral it could cancel it), a disarm sent anyway, and what
its thrusters now do said plainly. Handing over to a pilot: the same, but left armed, neutral tried once.
"""

from __future__ import annotations

import time

from rov_mav.flight.session.link import CHANNELS, NEUTRAL, mavlink, mode_name
from rov_mav.flight.run.outputs import NEUTRAL_HOLD, Passthrough
from rov_mav.flight.run.run_io import SAFE_STOP_CONFIRM, RunIO
from rov_mav.flight.run.run_options import HandOver, VehicleFailsafe

HANDOVER_CONFIRM = 0.2           # vehicle s to see neutral when handing over: a pilot's joystick may be writing over it
LOST_LINK_RETRY = 5.0            # wall s of neutral retries before a silent vehicle is reported as lost
REPORT_SLACK = 0.3               # wall s more for a late SERVO_OUTPUT_RAW (none when handing over: the pilot waits)


class SafeStop:
    """`stop(reason, notes)` -> the report, a line per step; `unconfirmed` names the steps the vehicle never
    confirmed (a run that would have exited 0 exits 1)."""

    def __init__(self, io: RunIO, output: Passthrough, handover: HandOver | None, last_command: list[int] | None):
        self.io = io
        self.output = output
        self.handover = handover
        self.last_command = last_command
        self.unconfirmed: list[str] = []
        self.report: list[str] = []

    def stop(self, reason: str, notes: list[str]) -> list[str]:
        io, s, changes = self.io, self.io.session, self.io.changes
        self.report = [f"stopping: {reason}", *notes]
        if s.vehicle is None:
            return self._finish(["no ArduSub vehicle was taken over: nothing was sent that changes one"])
        if not changes.anything:
            self.report.append("nothing had been changed on the vehicle" if not io.options.dry_run
                               else "dry run: no parameter changed, nothing armed, no override sent")
            return self._finish(self._reset_streams(alive=io.answering()))
        self.report += self._attempt("leave GUIDED", lambda: self.output.before_neutral(self.unconfirmed)) or []
        neutral, alive = self._neutral_until_seen()
        if not alive:
            return self._finish(self._link_gone())
        if not neutral and self.handover is None:
            io.pump_for(NEUTRAL_HOLD)           # give the vehicle time to apply it before letting go
        if self._attempt("release", lambda: s.release_overrides() or True):
            self.report.append("RC overrides on channels 1-8 released")
        else:
            self.unconfirmed.append("release")
        if changes.armed and self.handover is None:
            if self._attempt("disarm", lambda: s.arm(False)):
                self.report.append("disarmed (confirmed by HEARTBEAT)")
            else:
                self.report.append("disarm NOT confirmed")
                self.unconfirmed.append("disarm")
        self.report += self._attempt("restore mode", lambda: self.output.after_disarm(
            self.handover is not None, self.unconfirmed)) or []
        # The motors first, then the GCS sysid: a pilot's joystick must never reach an output on passthrough.
        self.report += self._restore(changes.restore_values())
        self.report += self._restore(changes.gcs_values())
        if self.handover is not None:
            self.report.append(self._handover_note())
        streams = self._attempt("message rates", lambda: self._reset_streams(alive=True))
        if streams is None:
            self.unconfirmed.append("reset message rates")
        return self._finish(streams or [])

    def _attempt(self, label: str, action):
        """action(), or None with a line in the report if it raised: one failed step must not skip the next ones."""
        try:
            return action()
        except Exception as exc:   # noqa: BLE001
            self.report.append(f"{label} FAILED: {exc!r}")
            return None

    def _neutral_until_seen(self) -> tuple[bool, bool]:
        """Neutral, confirmed by SERVO_OUTPUT_RAW: (confirmed, the vehicle answers). A glitch, a busy vehicle or a
        link coming back: keep sending it until it shows (handing over, the pilot's joystick may rule the outputs:
        once is enough while the vehicle answers)."""
        io = self.io
        confirm, slack = (HANDOVER_CONFIRM, 0.0) if self.handover is not None else (SAFE_STOP_CONFIRM, REPORT_SLACK)
        neutral = bool(self._attempt("neutral", lambda: io.neutral_confirmed(confirm, slack)))
        alive = neutral or io.answering()
        retry_until = time.monotonic() + LOST_LINK_RETRY
        while not neutral and (not alive or self.handover is None) and time.monotonic() < retry_until:
            neutral = bool(self._attempt("neutral", lambda: io.neutral_confirmed(confirm, slack)))
            alive = neutral or io.answering()
        self.report.append("neutral 1500 us on channels 1-8: sent, "
                           + ("confirmed by SERVO_OUTPUT_RAW" if neutral else "NOT confirmed"))
        if not neutral and (self.handover is None or not alive):   # handing over, the pilot's RC rules
            self.unconfirmed.append("neutral")
        return neutral, alive

    def _link_gone(self) -> list[str]:
        """No release: arriving together with the neutral, it would cancel it (both land before the vehicle next
        reads its RC input), leaving the flight command in place. Neutral stays the last word."""
        s, changes = self.io.session, self.io.changes
        self._attempt("disarm", lambda: s.fire(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0.0))
        pending = changes.functions + list(changes.gcs_values())
        self.unconfirmed += (["disarm"] if changes.armed else []) + (
            ["restore " + ", ".join(pending)] if pending else [])
        gcs_note = "".join(f" Set {name} back to {int(value)} when the link is back."
                           for name, (value, _) in changes.gcs_values().items())
        return ["disarm: sent, no answer",
                self.output.link_gone(self.last_command or [NEUTRAL] * CHANNELS, gcs_note)]

    def _restore(self, values: dict[str, tuple[float, int]]) -> list[str]:
        """Set the saved parameters back, all at once; one line for the confirmed, one for the rest."""
        if not values:
            return []
        failed = self._attempt("restore " + ", ".join(values), lambda: self.io.session.set_params(values))
        failed = list(values) if failed is None else failed
        lines = []
        if restored := [f"{n}={int(v)}" for n, (v, _) in values.items() if n not in failed]:
            lines.append("restored " + ", ".join(restored) + " (confirmed by PARAM_VALUE)")
        if failed:
            lines.append("NOT restored (no confirmation): " + ", ".join(f"{n}={int(values[n][0])}" for n in failed))
            self.unconfirmed.append("restore " + ", ".join(failed))
        return lines

    def _handover_note(self) -> str:
        s, changes = self.io.session, self.io.changes
        mode = mode_name(s.heartbeat.custom_mode)
        state = "armed" if s.armed else "NOT armed"
        if isinstance(self.handover, VehicleFailsafe):
            gcs = changes.gcs[1] if changes.gcs is not None else s.sysid
            return (f"left to the vehicle's failsafe: {state} in {mode}, thrusters back on ArduSub's motors, "
                    f"overrides released, nothing undone of what it did; its GCS failsafe (FS_GCS_ENABLE) now needs "
                    f"a station with sysid {gcs} sending heartbeats")
        took = s.clock.now() - self.handover.t_detected
        gcs = changes.gcs[1] if changes.gcs is not None else s.sysid
        station = self.handover.station
        follows = "ArduSub's mixer follows the GCS's joystick" if station is None or station.sysid == gcs else (
            f"ArduSub ignores the joystick of sysid {station.sysid} until its GCS sysid ({gcs}) is set to it")
        return (f"handed over {took:.2f} s of vehicle time after it was seen: {state} in {mode}, thrusters on their "
                f"motors ({self.output.handed_over(follows)}), overrides released")

    def _reset_streams(self, alive: bool) -> list[str]:
        streams = self.io.changes.streams
        if not streams or not alive:
            return []
        ok = all(self.io.session.command(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, msg_id, 0) ==
                 mavlink.MAV_RESULT_ACCEPTED for msg_id in streams)
        if not ok:
            self.unconfirmed.append("reset message rates")
        return ["message rates back to the vehicle's defaults" if ok else "message rates NOT all reset"]

    def _finish(self, lines: list[str]) -> list[str]:
        report = self.report + lines
        if self.unconfirmed:
            report.append(f"safe stop NOT complete: {'; '.join(self.unconfirmed)} not confirmed by the vehicle")
        for line in report:
            self.io.say(line, "warning" if "NOT" in line or "GONE" in line else "info")
        return report
