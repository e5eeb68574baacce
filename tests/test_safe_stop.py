"""The safe stop against a fake session, for every combination of what the run changed, the output path, a hand-over
or not, and every step the vehicle fails: each change undone in its order, no failed step skipping the ones after
it, exactly the failed steps named, nothing sent that the run did not change."""

from __future__ import annotations

import itertools
import time
from types import SimpleNamespace

import pytest

from rov_mav.flight.session.link import MANUAL, NEUTRAL, mavlink
from rov_mav.flight.run.outputs import Guided, MotorTest, Passthrough
from rov_mav.flight.session.vehicle_clock import RoundTrip
from rov_mav.flight.run.run_io import RunIO
from rov_mav.flight.run.run_options import HandOver, RunOptions
from rov_mav.flight.run import safe_stop
from rov_mav.flight.run.safe_stop import SafeStop
from rov_mav.flight.session.vehicle_changes import VehicleChanges

GUIDED_MODE = 4
FUNCTIONS = {f"SERVO{n}_FUNCTION": (float(32 + n), 4) for n in range(1, 9)}
GCS = ("MAV_GCS_SYSID", 255, 4)
STREAMS = [30, 32]


class FakeClock:
    rate = 1.0
    started = True

    def __init__(self, session):
        self.session = session

    @property
    def last_wall(self) -> float:
        return time.perf_counter() if self.session.alive else self.session.t0

    def now(self) -> float:
        return 100.0 + time.perf_counter() - self.session.t0

    @property
    def last_vehicle(self) -> float:
        return self.now() if self.session.alive else 0.0

    def wall_seconds(self, vehicle_seconds: float) -> float:
        return vehicle_seconds


class FakeSession:
    """Records what is sent, in order; answers as a vehicle that is `alive` (or silent), and refuses the steps in
    `fail` (neutral: SERVO_OUTPUT_RAW keeps the flight PWM; release: raises; disarm, mode: not confirmed;
    functions, gcs: PARAM_VALUE never comes; streams: SET_MESSAGE_INTERVAL refused)."""

    def __init__(self, alive: bool = True, fail: frozenset = frozenset(), mode: int = MANUAL):
        self.alive, self.fail = alive, fail
        self.t0 = time.perf_counter()
        self.clock = FakeClock(self)
        self.vehicle = SimpleNamespace(sysid=1, compid=1)
        self.heartbeat = SimpleNamespace(custom_mode=mode)
        self.origins: dict = {}
        self.taps: list = []
        self.armed = True
        self.sysid = 200
        self.motor_test: list[int] | None = None
        self.override: list[int] | None = [1700] * 8
        self.rejections = None
        self.round_trip = RoundTrip()
        self.calls: list[tuple] = []
        self.outputs = [1700] * 8

    def send_override(self, pwms) -> None:
        self.calls.append(("override", list(pwms)))
        self.override = list(pwms)
        if "neutral" not in self.fail:
            self.outputs = list(pwms)

    def send_motor_test(self, pwms) -> None:
        self.calls.append(("motor test", list(pwms)))
        self.motor_test = list(pwms)

    def end_motor_test(self) -> None:
        self.calls.append(("end motor test",))
        self.motor_test = None

    def poll(self, timeout: float):
        time.sleep(min(timeout, 0.002))
        if not self.alive:
            return []
        msg = SimpleNamespace(get_type=lambda: "SERVO_OUTPUT_RAW",
                              **{f"servo{i}_raw": v for i, v in enumerate(self.outputs, 1)})
        return [(msg, time.perf_counter())]

    def release_overrides(self) -> None:
        self.calls.append(("release",))
        if "release" in self.fail:
            raise OSError("the socket went away")

    def arm(self, arm: bool) -> bool:
        self.calls.append(("arm", arm))
        ok = self.alive and "disarm" not in self.fail
        self.armed = self.armed if not ok else arm
        return ok

    def fire(self, command: int, *params: float) -> None:
        self.calls.append(("fire", command, *params))

    def set_mode(self, mode: int) -> bool:
        self.calls.append(("mode", mode))
        if self.alive and "mode" not in self.fail:
            self.heartbeat.custom_mode = mode
            return True
        return False

    def set_params(self, values: dict) -> list[str]:
        self.calls.append(("params", tuple(values)))
        failing = ("functions" in self.fail and "SERVO1_FUNCTION" in values) or (
            "gcs" in self.fail and GCS[0] in values)
        return list(values) if failing or not self.alive else []

    def command(self, command: int, *params: float) -> int:
        self.calls.append(("command", command, *params))
        return mavlink.MAV_RESULT_DENIED if "streams" in self.fail else mavlink.MAV_RESULT_ACCEPTED

    def kinds(self) -> list[str]:
        return [c[0] for c in self.calls]


def changes_of(what: frozenset, mode_found: int | None) -> VehicleChanges:
    return VehicleChanges(saved_functions=dict(FUNCTIONS),
                          functions=list(FUNCTIONS) if "functions" in what else [],
                          gcs=GCS if "gcs" in what else None, overrides_sent=True,
                          armed="armed" in what, streams=list(STREAMS) if "streams" in what else [],
                          mode_found=mode_found)


def stop_with(session: FakeSession, changes: VehicleChanges, path: str, handover: bool):
    io = RunIO(session, RunOptions(link_timeout=0.5), changes, sinks=[])
    output = {"thrusters": Passthrough, "motor-test": MotorTest}.get(path)
    output = output(io) if output is not None else Guided(io, SimpleNamespace(mode=GUIDED_MODE, hold=lambda: None))
    if path == "motor-test":
        session.motor_test = [1700] * 8
    taken = HandOver("pilot takeover", session.clock.now()) if handover else None
    stop = SafeStop(io, output, taken, [1700] * 8)
    return stop, stop.stop("the test", [])


@pytest.fixture(autouse=True)
def _quick(monkeypatch):
    """The stop's waits, shortened: the fake vehicle answers at once or never."""
    monkeypatch.setattr(safe_stop, "SAFE_STOP_CONFIRM", 0.02)
    monkeypatch.setattr(safe_stop, "LOST_LINK_RETRY", 0.03)
    monkeypatch.setattr(safe_stop, "REPORT_SLACK", 0.01)
    monkeypatch.setattr(safe_stop, "HANDOVER_CONFIRM", 0.02)
    monkeypatch.setattr(safe_stop, "NEUTRAL_HOLD", 0.01)


CHANGED = [frozenset(c) for n in range(4) for c in itertools.combinations(("functions", "gcs", "armed", "streams"), n)]
STEPS = ["neutral", "release", "disarm", "functions", "gcs", "streams", "mode"]


@pytest.mark.parametrize("path", ["thrusters", "motor-test", "ardusub-guided"])
@pytest.mark.parametrize("handover", [False, True])
@pytest.mark.parametrize("failing", [None, *STEPS])
def test_every_change_is_undone_in_order_and_only_failed_steps_are_named(path, handover, failing):
    for changed in CHANGED:
        if path != "thrusters" and "functions" in changed:
            continue                      # the motor test and GUIDED leave the outputs on their motors
        mode_found = MANUAL if path == "ardusub-guided" else None
        session = FakeSession(fail=frozenset([failing] if failing else []),
                              mode=GUIDED_MODE if path == "ardusub-guided" else MANUAL)
        stop, report = stop_with(session, changes_of(changed, mode_found), path, handover)
        kinds = session.kinds()
        where = f"{path}, changed {sorted(changed)}, failing {failing}, handover {handover}: {session.calls}"
        # neutral first (after leaving GUIDED), then the release, always: a failed step never skips the next
        assert kinds[kinds.index("override")] == "override" and session.calls[kinds.index("override")][1] == \
            [NEUTRAL] * 8, where
        assert "release" in kinds and kinds.index("override") < kinds.index("release"), where
        # disarmed only what this run armed, never when handing over
        disarms = [c for c in session.calls if c == ("arm", False)]
        assert len(disarms) == (1 if "armed" in changed and not handover else 0), where
        params = [c[1] for c in session.calls if c[0] == "params"]
        expected = ([tuple(FUNCTIONS)] if "functions" in changed else []) + ([(GCS[0],)] if "gcs" in changed else [])
        assert params == expected, where          # the motors before the GCS sysid, nothing else
        assert ("command" in kinds) == ("streams" in changed), where
        if path == "ardusub-guided":
            modes = [c[1] for c in session.calls if c[0] == "mode"]
            assert modes[0] == MANUAL and kinds.index("mode") < kinds.index("override"), where   # GUIDED left first
        if path == "motor-test":
            assert "end motor test" in kinds and session.motor_test is None, where
        # exactly the failed steps are named, and only then is the stop incomplete
        applies = {"neutral": not handover, "release": True, "disarm": "armed" in changed and not handover,
                   "functions": "functions" in changed, "gcs": "gcs" in changed, "streams": "streams" in changed,
                   "mode": path == "ardusub-guided"}
        named = {"neutral": "neutral", "release": "release", "disarm": "disarm", "functions": "restore SERVO1_FUNCTION",
                 "gcs": f"restore {GCS[0]}", "streams": "reset message rates", "mode": "leave GUIDED"}
        if failing is not None and applies[failing]:
            assert any(u.startswith(named[failing]) for u in stop.unconfirmed), where
            assert report[-1].startswith("safe stop NOT complete: "), where
        else:
            assert stop.unconfirmed == [] and not report[-1].startswith("safe stop NOT complete"), where


@pytest.mark.parametrize("path", ["thrusters", "motor-test"])
def test_a_silent_vehicle_gets_neutral_and_a_disarm_but_no_release(path):
    """The link is gone: neutral kept up for the retry window, a disarm fired anyway, no release (it could cancel the
    neutral), every pending restore named, and what the thrusters now do said plainly."""
    session = FakeSession(alive=False)
    started = time.monotonic()
    stop, report = stop_with(session, changes_of(frozenset({"functions", "gcs", "armed", "streams"}) if path ==
                                                 "thrusters" else frozenset({"gcs", "armed"}), None), path, False)
    kinds = session.kinds()
    assert time.monotonic() - started >= safe_stop.LOST_LINK_RETRY    # neutral kept up that long
    assert kinds.count("override") > 1 and "release" not in kinds and "params" not in kinds
    assert ("fire", mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0.0) in session.calls
    assert "disarm" in stop.unconfirmed and any(u.startswith("restore") for u in stop.unconfirmed)
    gone = next(line for line in report if line.startswith("THE LINK IS GONE"))
    if path == "thrusters":
        assert "HOLD THEIR LAST COMMAND" in gone and "SERVO1_FUNCTION=33" in gone
    else:
        assert "motor test" in gone and f"Set {GCS[0]} back to {GCS[1]}" in gone and session.motor_test is None


def test_nothing_changed_sends_nothing_but_the_stream_reset():
    session = FakeSession()
    changes = VehicleChanges(streams=list(STREAMS))
    stop, report = stop_with(session, changes, "thrusters", False)
    assert set(session.kinds()) == {"command"} and stop.unconfirmed == []
    assert "nothing had been changed on the vehicle" in report
