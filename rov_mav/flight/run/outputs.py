"""How a run's commands reach the thrusters, one strategy per path, each owning its take-over, its sending, what it
adds to neutral when telemetry is stale, its part of the safe stop and of a hand-over:

- `Passthrough` (--output thrusters): SERVO1..8_FUNCTION switched to RCIN1..8 passthrough (each confirmed), MANUAL,
  armed; the PWMs as RC_CHANNELS_OVERRIDE. Passthrough is not gated by arming and keeps the last PWM.
- `MotorTest` (--output motor-test): outputs left on their motors, MANUAL, armed, then ArduSub's motor test
  (MAV_CMD_DO_MOTOR_TEST, board order, raw PWM) while neutral overrides are held as pilot input; ArduSub ends the test,
  disarming, 0.5 s after the last command (ArduSub/motors.cpp, verify_motor_test).
- `Guided` (--controller ardusub-guided): no law of ours; GUIDED, armed, the reference streamed to ArduSub's position
  controller; the stop first leaves GUIDED for MANUAL and ends by setting back the mode it found.
Each starts the same way: neutral overrides held, then proven (RC_CHANNELS echoing a probe inside every dead band).
"""

from __future__ import annotations

import time

from rov_mav.flight.run.guided import GuidedStream
from rov_mav.flight.session.link import ACCEL_TARGETS_FROM, CHANNELS, MANUAL, MOTOR_TEST_TIMEOUT, NEUTRAL, mode_name
from rov_mav.flight.run.run_io import RunIO
from rov_mav.flight.run.run_options import Abort
from rov_mav.flight.session.vehicle_changes import PASSTHROUGH_BASE

NEUTRAL_HOLD = 0.3               # vehicle s of neutral before switching outputs
OVERRIDE_PROBE = 1510            # us: inside the T200 dead band at every voltage (1476-1528 us at 20 V)
PROBE_WAIT = 5.0                 # vehicle s for RC_CHANNELS (asked at 2 Hz) to echo the probe, through loss
MOTOR_TEST_START = 13.0          # vehicle s for the first DO_MOTOR_TEST to be accepted: ArduSub refuses one for 10 s
                                 # after an earlier test timed out, and retries a refused start every 2 s


class Passthrough:
    """--output thrusters: RC overrides on RCIN passthrough."""

    outputs_echo_overrides = True    # SERVO_OUTPUT_RAW shows the RC input: our overrides, or a stranger's

    def __init__(self, io: RunIO):
        self.io = io

    @property
    def flight_mode(self) -> int:
        return MANUAL

    def take_over(self) -> None:
        """Neutral held and proven, then this path's switch to flying."""
        io = self.io
        io.session.override_rate = io.options.rate
        io.send_neutral()
        io.pump_for(NEUTRAL_HOLD)
        self._prove_overrides()
        io.send_neutral()
        io.pump_for(NEUTRAL_HOLD)
        self._switch()

    def _switch(self) -> None:
        """Each motor k's output (wherever the vehicle has it: `io.motors`) to RCINk passthrough, then armed."""
        io, s, changes = self.io, self.io.session, self.io.changes
        names = io.motors.names()
        passthrough = {name: (float(PASSTHROUGH_BASE + k), changes.saved_functions[name][1])
                       for k, name in enumerate(names, 1)}
        changes.functions += [name for name in passthrough if name not in changes.functions]
        if failed := s.set_params(passthrough):
            raise Abort("the vehicle did not confirm " + ", ".join(f"{n} = {int(passthrough[n][0])}" for n in failed)
                        + " (RCIN passthrough)")
        io.say(f"{', '.join(names)} set to RCIN1..{len(names)} passthrough (confirmed)")
        self._arm_in_manual()
        io.say("armed in MANUAL")

    def _arm_in_manual(self) -> None:
        s = self.io.session
        if s.heartbeat.custom_mode != MANUAL and not s.set_mode(MANUAL):
            raise Abort("the vehicle did not enter MANUAL mode")
        self.io.changes.armed = True
        before = s.texts_seen
        if not s.arm(True):
            refusal = ("Arm: ", "PreArm: ")     # `AP_Arming::check_failed`: sent after the COMMAND_ACK, maybe
            s.wait(lambda m: m.get_type() == "STATUSTEXT" and m.text.startswith(refusal), s.clock.wall_seconds(1.0))
            said = [text for text in s.texts_after(before) if text.startswith(refusal)]
            raise Abort("arming failed: " + ("the vehicle refused it: " + "; ".join(said) if said
                                             else "the vehicle refused or did not confirm it"))
        self.io.flying_since = s.clock.now()

    def _prove_overrides(self) -> None:
        """ArduSub takes overrides only from its GCS sysid, and none with RC_OVERRIDE_TIME = 0: before any output
        is switched, hold a probe value inside every T200 dead band (no thrust, whatever drives the outputs) until
        RC_CHANNELS shows it on all eight channels."""
        io, s = self.io, self.io.session
        s.send_override([OVERRIDE_PROBE] * CHANNELS)
        deadline = time.monotonic() + s.clock.wall_seconds(PROBE_WAIT) + 0.5
        while time.monotonic() < deadline:
            io.interrupt()
            for msg, _ in s.poll(0.02):
                io.track(msg)
                if msg.get_type() == "RC_CHANNELS" and all(
                        getattr(msg, f"chan{i}_raw") == OVERRIDE_PROBE for i in range(1, CHANNELS + 1)):
                    io.say("RC overrides accepted by the vehicle (RC_CHANNELS echoes them)")
                    return
        raise Abort(f"the vehicle does not apply our RC overrides (RC_CHANNELS never showed {OVERRIDE_PROBE} us): "
                    f"check that sysid {s.sysid} is its GCS sysid (MAV_GCS_SYSID / SYSID_MYGCS) and that "
                    "RC_OVERRIDE_TIME is not 0")

    def send(self, pwm) -> list[int]:
        """The tick's eight PWMs; returns them as sent."""
        self.io.session.send_override(pwm)
        return self.io.session.override

    def on_stale(self) -> None:
        """Telemetry went stale and neutral was sent: anything more this path holds."""

    def before_neutral(self, unconfirmed: list[str]) -> list[str]:
        """The stop's first step, before neutral; its report lines."""
        return []

    def after_disarm(self, handing_over: bool, unconfirmed: list[str]) -> list[str]:
        """The stop's step after the disarm; its report lines."""
        return []

    def link_gone(self, last: list[int], gcs_note: str) -> str:
        """What the thrusters do when the vehicle no longer answers, said in the stop's report."""
        changes = self.io.changes
        return ("THE LINK IS GONE: the vehicle did not answer. Its thrusters HOLD THEIR LAST COMMAND: RCIN "
                "passthrough keeps the last PWM that reached it (the last flight command sent was "
                f"{last}; neutral was sent after it, unconfirmed), arming does not gate it and ArduSub's "
                "failsafes do not reset channels 7-8."
                + (" SERVOn_FUNCTION were NOT restored (still RCIN passthrough): restore "
                   + ", ".join(f"{n}={int(changes.saved_functions[n][0])}" for n in changes.functions)
                   + " as soon as the link is back (the next `rov-mav run` does it when it ends)."
                   if changes.functions else ""))

    def handed_over(self, follows: str) -> str:
        """Who drives the thrusters once handed over."""
        return follows


class MotorTest(Passthrough):
    """--output motor-test: ArduSub's motor test, the outputs left on their motors."""

    outputs_echo_overrides = False

    def _switch(self) -> None:
        """MANUAL, armed, then the motor test held at neutral until the vehicle accepts it: the outputs stay on their
        motors, the neutral overrides held as pilot input (ArduSub's pilot-input failsafe disarms without it)."""
        io, s = self.io, self.io.session
        self._arm_in_manual()
        s.send_motor_test([NEUTRAL] * CHANNELS)
        start = s.clock.now()
        wall_end = time.monotonic() + s.clock.wall_seconds(MOTOR_TEST_START) + 1.0
        while s.motor_test_answers["accepted"] == 0:
            io.interrupt()
            if s.clock.now() - start > MOTOR_TEST_START or time.monotonic() > wall_end or not s.armed:
                raise Abort(f"the vehicle did not accept MAV_CMD_DO_MOTOR_TEST within {MOTOR_TEST_START:g} s "
                            f"({s.motor_test_answers['refused']} refused): ArduSub refuses it while disarmed and "
                            "for 10 s after an earlier motor test timed out (its STATUSTEXT says which)")
            io.pump(0.02)
        io.say("armed in MANUAL, the thrusters through ArduSub's motor test (MAV_CMD_DO_MOTOR_TEST, accepted): "
               f"ArduSub stops them and disarms {MOTOR_TEST_TIMEOUT:g} s after our last command")

    def send(self, pwm) -> list[int]:
        self.io.session.send_motor_test(pwm)
        return self.io.session.motor_test

    def after_disarm(self, handing_over: bool, unconfirmed: list[str]) -> list[str]:
        s = self.io.session
        if s.motor_test is None and s.motor_test_stopped is None:
            return []
        s.end_motor_test()
        return [f"motor test no longer sent: ArduSub ends it {MOTOR_TEST_TIMEOUT:g} s later (and disarms)"]

    def link_gone(self, last: list[int], gcs_note: str) -> str:
        s = self.io.session
        if s.motor_test is None:
            return super().link_gone(last, gcs_note)
        s.end_motor_test()
        return ("THE LINK IS GONE: the vehicle did not answer. Its thrusters were driven by ArduSub's motor test, "
                f"which it ends {MOTOR_TEST_TIMEOUT:g} s of vehicle time after the last command reached it: "
                f"outputs neutral, vehicle disarmed (the last flight command sent was {last}; neutral was sent "
                "after it, unconfirmed)." + gcs_note)

    def handed_over(self, follows: str) -> str:
        return (f"ArduSub ends the motor test {MOTOR_TEST_TIMEOUT:g} s after our last command and disarms: "
                f"arm it again to drive; then {follows}")


class Guided(Passthrough):
    """--controller ardusub-guided: ArduSub's own position controller in GUIDED, the outputs on their motors."""

    outputs_echo_overrides = False

    def __init__(self, io: RunIO, stream: GuidedStream):
        super().__init__(io)
        self.stream = stream

    @property
    def flight_mode(self) -> int:
        return self.stream.mode

    def _switch(self) -> None:
        """GUIDED, then armed: the outputs stay on their motors (ArduSub's mixer), the neutral overrides held."""
        io, s = self.io, self.io.session
        version = s.firmware_version()
        self.stream.accelerations = version is not None and version >= ACCEL_TARGETS_FROM
        io.say(f"ArduSub {'.'.join(map(str, version)) if version else '(version unknown)'}: GUIDED targets with "
               + ("the acceleration fed forward" if self.stream.accelerations else
                  f"position and velocity only (acceleration needs {'.'.join(map(str, ACCEL_TARGETS_FROM))})"))
        io.changes.mode_found = s.heartbeat.custom_mode
        if not s.set_mode(self.flight_mode):
            raise Abort(f"the vehicle did not enter {mode_name(self.flight_mode)} mode (ArduSub needs a position "
                        "estimate for it)")
        io.changes.armed = True
        if not s.arm(True):
            raise Abort("arming failed: the vehicle refused or did not confirm it")
        io.flying_since = s.clock.now()
        io.say(f"armed in {mode_name(self.flight_mode)}: SET_POSITION_TARGET_LOCAL_NED (position, velocity, yaw) "
               f"at {self.stream.rate:g} Hz of vehicle time")

    def on_stale(self) -> None:
        self.stream.hold()

    def before_neutral(self, unconfirmed: list[str]) -> list[str]:
        """Out of GUIDED to MANUAL (its mixer of the neutral overrides reads 1500), unless someone else already
        changed the mode."""
        s = self.io.session
        if self.io.changes.mode_found is None or s.heartbeat is None or s.heartbeat.custom_mode != self.flight_mode:
            return []
        self.stream.hold()
        if s.set_mode(MANUAL):
            return [f"{mode_name(self.flight_mode)} left for MANUAL (confirmed by HEARTBEAT)"]
        unconfirmed.append("leave GUIDED")
        return [f"{mode_name(self.flight_mode)} NOT left (no confirmation)"]

    def after_disarm(self, handing_over: bool, unconfirmed: list[str]) -> list[str]:
        """The mode the run found (MANUAL if that was GUIDED), unless handing over."""
        s, found = self.io.session, self.io.changes.mode_found
        if handing_over:
            return []
        mode = MANUAL if found in (None, self.flight_mode) else found
        if found is None or s.heartbeat is None or s.heartbeat.custom_mode == mode:
            return []
        if s.set_mode(mode):
            return [f"mode back to {mode_name(mode)} (confirmed by HEARTBEAT)"]
        unconfirmed.append(f"mode {mode_name(mode)}")
        return [f"mode NOT back to {mode_name(mode)} (no confirmation)"]
