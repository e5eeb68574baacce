"""Who else is on the link, and whose vehicle it is: the rules by which a run decides, before it sends anything,
whether the vehicle is free, abandoned or someone else's, and by which it notices while flying that someone else
is driving.

On a real BlueROV2 the pilot's QGroundControl or Cockpit is connected the whole dive (as GCS sysid 255), sending
heartbeats and, with a joystick, MANUAL_CONTROL at about 25 Hz. ArduSub (GCS_MAVLink_Sub.cpp, MANUAL_CONTROL and
RC_CHANNELS_OVERRIDE handling) applies both only from a GCS sysid, and `Sub::transform_manual_control_to_rc_override`
(ArduSub/joystick.cpp) writes them over RC channels 1-8 (4.5: 1-11) - the eight thrusters on RCIN passthrough.
MAV_CMD_DO_MOTOR_TEST it takes from any sysid (ArduSub/motors.cpp): a station sending it drives the thrusters too.
A station on another link of the vehicle is seen only as ArduPilot's routing shows it (`MAVLink_routing.cpp`): its
HEARTBEAT (unless it shares our sysid and component), never what it sends the vehicle; what it writes shows in the
vehicle's RC_CHANNELS and SERVO_OUTPUT_RAW, interleaved with our overrides (`OverrideEcho`).
Pure: no I/O; times are vehicle seconds.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

STICK_DEAD_BAND = 100        # of MANUAL_CONTROL's +-1000: a joystick further from rest than this is a pilot driving
Z_REST = 500                 # MANUAL_CONTROL z (throttle) at rest, 0..1000 in ArduSub
RC_STEADY = 3                # us: RC input samples further apart than this mean someone is writing it
ECHO_TOLERANCE = 1           # us between an override we sent and the RC input the vehicle reports
ECHO_MEMORY = 512            # overrides remembered (>= 5 vehicle s at 50 Hz plus the held resends)
UINT16_MAX = 65535
DO_MOTOR_TEST = 209          # MAV_CMD_DO_MOTOR_TEST
MAV_TYPE_GCS = 6


@dataclass
class Station:
    """One other (sysid, compid) seen on the link, and what it did."""

    sysid: int
    compid: int
    first_seen: float = 0.0              # vehicle s
    ground_station: bool = False         # its HEARTBEAT says MAV_TYPE_GCS
    heartbeats: int = 0
    manual_control: int = 0
    overrides: int = 0
    motor_tests: int = 0
    last_drive: float = -np.inf          # vehicle s of its last MANUAL_CONTROL, effective RC override or motor test
    stick: tuple[int, int, int, int] | None = None    # (x, y, z, r) of its last MANUAL_CONTROL
    deflected_at: float | None = None    # vehicle s its joystick was last beyond the dead band

    def describe(self) -> str:
        what = []
        if self.manual_control:
            x, y, z, r = self.stick
            state = "moving" if self.deflected_at is not None and self.deflected_at >= self.last_drive else "at rest"
            what.append(f"MANUAL_CONTROL x {self.manual_control}, joystick {state} (x={x}, y={y}, z={z}, r={r})")
        if self.overrides:
            what.append(f"RC_CHANNELS_OVERRIDE x {self.overrides}")
        if self.motor_tests:
            what.append(f"MAV_CMD_DO_MOTOR_TEST x {self.motor_tests}")
        if self.heartbeats and not what:
            what.append("heartbeats only")
        return f"station sysid {self.sysid} component {self.compid} ({'; '.join(what)})"


def stick_deflected(x: int, y: int, z: int, r: int) -> bool:
    """A joystick beyond the dead band on any axis (x, y, r rest at 0; z rests at 500)."""
    return max(abs(x), abs(y), abs(r), abs(z - Z_REST)) > STICK_DEAD_BAND


def overrides_anything(values: list[int]) -> bool:
    """Does an RC_CHANNELS_OVERRIDE's 18 fields set any channel (1-8: not 0/UINT16_MAX; 9-18: not 0/UINT16_MAX or
    UINT16_MAX-1, which only ignore or release)?"""
    return any(v not in (0, UINT16_MAX) for v in values[:8]) or \
        any(v not in (0, UINT16_MAX, UINT16_MAX - 1) for v in values[8:])


class StationWatch:
    """Everything other stations send that the link shows us; feed it with `observe`."""

    def __init__(self, vehicle_sysid: int):
        self.vehicle_sysid = vehicle_sysid
        self.stations: dict[tuple[int, int], Station] = {}

    def observe(self, msg, t: float) -> None:
        """One message that is neither from the vehicle nor ours, at vehicle time t."""
        kind = msg.get_type()
        if kind not in ("HEARTBEAT", "MANUAL_CONTROL", "RC_CHANNELS_OVERRIDE", "COMMAND_LONG", "COMMAND_INT"):
            return
        key = (msg.get_srcSystem(), msg.get_srcComponent())
        station = self.stations.setdefault(key, Station(*key, first_seen=t))
        if kind == "HEARTBEAT":
            station.heartbeats += 1
            station.ground_station = station.ground_station or msg.type == MAV_TYPE_GCS
        elif kind == "MANUAL_CONTROL" and msg.target == self.vehicle_sysid:
            station.manual_control += 1
            station.last_drive = t
            station.stick = (msg.x, msg.y, msg.z, msg.r)
            if stick_deflected(*station.stick):
                station.deflected_at = t
        elif kind == "RC_CHANNELS_OVERRIDE" and msg.target_system in (0, self.vehicle_sysid) and \
                overrides_anything([getattr(msg, f"chan{i}_raw") for i in range(1, 19)]):
            station.overrides += 1
            station.last_drive = t
        elif kind in ("COMMAND_LONG", "COMMAND_INT") and msg.command == DO_MOTOR_TEST and \
                msg.target_system in (0, self.vehicle_sysid):
            station.motor_tests += 1
            station.last_drive = t

    def drivers(self, since: float) -> list[Station]:
        """Stations that sent MANUAL_CONTROL, an effective RC override or a motor test at or after `since`."""
        return [s for s in self.stations.values() if s.last_drive >= since]

    def overriding(self, since: float) -> list[Station]:
        """Drivers writing the outputs themselves: RC overrides or motor tests."""
        return [s for s in self.drivers(since) if s.overrides or s.motor_tests]

    def pilots_moving(self, since: float) -> list[Station]:
        """Stations whose joystick was beyond the dead band at or after `since`."""
        return [s for s in self.stations.values() if s.deflected_at is not None and s.deflected_at >= since]

    def joysticks(self, since: float, sysid: int | None = None) -> list[Station]:
        """Stations sending MANUAL_CONTROL since `since` (from `sysid` only, if given)."""
        return [s for s in self.drivers(since) if s.manual_control and (sysid is None or s.sysid == sysid)]

    def joined(self, since: float, gcs_sysids: set[int]) -> list[Station]:
        """Ground stations first heard after `since` (a heartbeat the vehicle forwards from another link) on a sysid
        the vehicle takes as its GCS: their joystick would drive the thrusters."""
        return [s for s in self.stations.values()
                if s.first_seen > since and s.ground_station and s.sysid in gcs_sysids]

    def sysids(self) -> set[int]:
        return {sysid for sysid, _ in self.stations}


@dataclass(frozen=True)
class Sighting:
    """What a run saw in its observation window, before sending anything."""

    since: float                                 # vehicle s the window started
    armed: bool
    passthrough: list[str]                       # SERVOn_FUNCTION found on RCIN passthrough
    rc: list[list[int]] = field(default_factory=list)   # RC_CHANNELS ch1-8 samples in the window


@dataclass(frozen=True)
class Verdict:
    refusal: str | None                          # why the run must not touch the vehicle (one line), or None
    abandoned: list[str]                         # passthrough outputs nobody drives: neutral first, restore at end
    resting_pilots: list[Station]                # joysticks at rest: ArduSub applies them if on the GCS sysid


def judge(sighting: Sighting, watch: StationWatch, force: bool) -> Verdict:
    """Is the vehicle ours to take? Someone else's when it is armed, when a station drives it (an RC override, or a
    joystick beyond the dead band), or when its RC input changes with no visible station. Passthrough outputs are
    abandoned (a run that died) only when none of these holds. With `force` nothing is refused."""
    refusals = []
    drivers = watch.drivers(sighting.since)
    if sighting.armed:
        refusals.append("the vehicle is already armed by someone else (another station, or a run flying it)")
    overriding = watch.overriding(sighting.since)
    if overriding:
        refusals.append("another station is driving it: " + ", ".join(s.describe() for s in overriding))
    moving = [s for s in watch.pilots_moving(sighting.since) if s not in overriding]
    if moving:
        refusals.append("a pilot is driving it: " + ", ".join(s.describe() for s in moving))
    rc = np.array(sighting.rc, dtype=float).reshape(-1, 8)
    if len(rc) > 1 and not overriding and not moving and np.ptp(rc, axis=0).max() > RC_STEADY:
        changing = [f"RC{i + 1} {int(rc[:, i].min())}-{int(rc[:, i].max())}" for i in range(8)
                    if np.ptp(rc[:, i]) > RC_STEADY]
        refusals.append("its RC input is changing with no station visible on this link (" + ", ".join(changing)
                        + "): someone is driving it through another route")
    resting = [s for s in drivers if s.manual_control and s not in moving and not s.overrides]
    if refusals and not force:
        return Verdict("; ".join(refusals), [], resting)
    return Verdict(None, list(sighting.passthrough), resting)


class OverrideEcho:
    """Does the vehicle show what this run sends? Keeps the last ECHO_MEMORY overrides (channels 1-8).

    A report is ours when channels 1-8 equal any recent override (by value, not by time: timestamps would compare the
    vehicle's time_boot_ms with our estimate of it at sending, which runs ahead whenever the vehicle stalls, and so
    would take our own command for a stranger's) and, for RC_CHANNELS, channels 9-16 are as they were when the run
    began (it never writes them: a pilot's buttons or another station's override would). A pilot's joystick
    interleaves with our overrides (ArduSub keeps whichever came last), so its values show in some reports, not all,
    of RC_CHANNELS and (passthrough outputs show the RC input) SERVO_OUTPUT_RAW. One report unlike ours is someone
    else writing: a row the vehicle reports is one it was sent (MAVLink's CRC keeps a damaged report out), and
    nothing but a station writes a row we did not send while we hold the overrides (measured, tools/pilot_join.py:
    waiting for two within 1 s took a joystick on another link up to 2 s of vehicle time to notice)."""

    def __init__(self, capacity: int = ECHO_MEMORY):
        self._sent = np.full((capacity, 8), np.nan)   # a ring of the last `capacity` overrides (NaN: unused)
        self._next = 0
        self._upper: np.ndarray | None = None       # RC 9-16 as the run found them

    def sent_now(self, pwm) -> None:
        self._sent[self._next % len(self._sent)] = np.asarray(pwm[:8], dtype=float)
        self._next += 1

    def rc(self, channels: list[int]) -> bool:
        """An RC_CHANNELS report (channels 1-16); True when someone else is writing."""
        row = np.asarray(channels, dtype=float)
        if self._upper is None:
            self._upper = row[8:16].copy()
        return not (self._ours(row[:8]) and np.array_equal(row[8:16], self._upper))

    def servo(self, outputs: list[int]) -> bool:
        """A SERVO_OUTPUT_RAW report (outputs 1-8 on RCIN passthrough); True as `rc`."""
        return not self._ours(np.asarray(outputs, dtype=float))

    def _ours(self, row: np.ndarray) -> bool:
        if self._next == 0:
            return True
        return bool(np.any(np.all(np.abs(self._sent - row) <= ECHO_TOLERANCE, axis=1)))
