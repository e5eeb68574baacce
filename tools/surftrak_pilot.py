"""A pilot flying a transect in ArduSub's SURFTRAK, for `tools/transect_table.py`'s SURFTRAK row: the way BlueROV2
survey teams fly one by hand, the height held by the vehicle from its rangefinder, the speed and the line by the
pilot's sticks.

On its own link of a `rov-mav sim-bridge` process (a GCS at sysid 255, a pymavlink station as QGroundControl is one),
the pilot arms in ALT_HOLD, switches to SURFTRAK (mode 21: `ModeSurftrak::init` takes the range then read as its
target, ArduSub/mode_surftrak.cpp), waits HOLD s, then pushes forward: the forward stick from the speed over the
ground the vehicle reports (LOCAL_POSITION_NED, the DVL's), proportional plus a trim it learns as a pilot settles on a
stick position; the lateral stick from the distance off the line the same estimate shows (a pilot watching the track
on the map); the yaw stick centred, so the vehicle holds its heading. At the line's end, sticks centred, a short
hold, then disarm. MANUAL_CONTROL goes out at STICK_RATE Hz of vehicle time (ArduSub's pilot-input failsafe waits
FS_PILOT_TIMEOUT without it). What it records (the estimate, the truth from SIM_STATE and SimHeight, the sounder's
DISTANCE_SENSOR) gives the same figures as a run's `terrain` block (`rov_mav.mission.metrics.terrain_metrics`).
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
from pymavlink import mavutil

from rov_mav.flight.session.truth import Truth
from rov_mav.mission.metrics import terrain_metrics

SURFTRAK, ALT_HOLD = 21, 2       # ArduSub's mode numbers (ArduSub/mode.h `Mode::Number`)
STICK_RATE = 10.0                # vehicle Hz of MANUAL_CONTROL
HOLD = 8.0                       # vehicle s held in SURFTRAK before the line, and 3 s after it
RAMP = 3.0                       # vehicle s the pilot takes to reach the speed (the missions' ramp_time)
SPEED_GAIN, TRIM_GAIN = 2500.0, 1500.0     # stick per m/s of speed error, and per m of it (the trim learnt)
POSITION_GAIN = 0.5                        # m/s asked per m from the start, while holding there
LINE_GAIN, LINE_DAMPING, LINE_TRIM = 1500.0, 2500.0, 400.0   # stick per m off the line, per m/s, per m s
WAIT = 30.0                      # wall s for the vehicle to answer


class SurftrakPilot:
    """`fly(length, speed, altitude)` -> the samples; `metrics(...)` -> the terrain figures."""

    def __init__(self, port: int, speedup: float):
        self.conn = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=255, source_component=190,
                                               dialect="ardupilotmega")
        self.speedup = speedup
        self.truth = Truth()
        self.now = 0.0                   # vehicle s: the newest time_boot_ms heard
        self.mode: int | None = None
        self.armed = False
        self.position: np.ndarray | None = None      # the estimate: x, y, z, vx, vy
        self.sounding: float | None = None
        self.rows: list[tuple] = []      # t, x, y, z, true n, e, d, true height, sounding, x_d, target

    def close(self) -> None:
        self.conn.close()

    def _pump(self, timeout: float = 0.0) -> None:
        msg = self.conn.recv_match(blocking=timeout > 0, timeout=timeout or None)
        while msg is not None:
            self._take(msg)
            msg = self.conn.recv_match(blocking=False)

    def _take(self, msg) -> None:
        kind = msg.get_type()
        if hasattr(msg, "time_boot_ms"):
            self.now = max(self.now, msg.time_boot_ms * 1e-3)
        if kind == "HEARTBEAT" and msg.get_srcSystem() == 1 and msg.get_srcComponent() == 1:
            self.mode = msg.custom_mode
            self.armed = bool(msg.base_mode & mavutil.mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
        elif kind == "LOCAL_POSITION_NED":
            self.position = np.array([msg.x, msg.y, msg.z, msg.vx, msg.vy])
        elif kind == "DISTANCE_SENSOR" and msg.orientation == mavutil.mavlink.MAV_SENSOR_ROTATION_PITCH_270:
            self.sounding = msg.current_distance * 0.01 if msg.signal_quality > 0 else None
        self.truth.update(msg, self.now)

    def _heartbeat(self) -> None:
        mav = mavutil.mavlink
        self.conn.mav.heartbeat_send(mav.MAV_TYPE_GCS, mav.MAV_AUTOPILOT_INVALID, 0, 0, mav.MAV_STATE_ACTIVE)

    def _sticks(self, x: float = 0.0, y: float = 0.0) -> None:
        clip = lambda v: int(max(-1000.0, min(1000.0, v)))   # noqa: E731
        self.conn.mav.manual_control_send(1, clip(x), clip(y), 500, 0, 0)

    def _until(self, done, what: str) -> None:
        """Heartbeat and centred sticks until done() (RuntimeError naming `what` after WAIT wall s)."""
        deadline = time.monotonic() + WAIT
        while not done():
            if time.monotonic() > deadline:
                raise RuntimeError(f"the vehicle did not {what} within {WAIT:g} s")
            self._heartbeat()
            self._sticks()
            self._pump(0.1)

    def _ask(self, message: int, rate: float) -> None:
        self.conn.mav.command_long_send(1, 1, mavutil.mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 0, message, 1e6 / rate,
                                        0, 0, 0, 0, 0)

    def _set_mode(self, mode: int) -> None:
        self.conn.mav.set_mode_send(1, mavutil.mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, mode)

    def _arm(self, arm: bool) -> None:
        self.conn.mav.command_long_send(1, 1, mavutil.mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0, float(arm),
                                        0, 0, 0, 0, 0, 0)

    def _fly_for(self, seconds: float, stick) -> None:
        """Sticks from stick(t) at STICK_RATE for `seconds` of vehicle time, recording as it goes."""
        end, next_stick = self.now + seconds, 0.0
        deadline = time.monotonic() + WAIT + seconds / self.speedup * 3.0
        while self.now < end:
            if time.monotonic() > deadline:
                raise RuntimeError("the vehicle's clock stopped")
            self._pump(0.02 / self.speedup)
            if self.now >= next_stick:
                self._heartbeat()
                self._sticks(*stick(self.now))
                next_stick = self.now + 1.0 / STICK_RATE

    def fly(self, length: float, speed: float, altitude: float) -> None:
        """Arm, SURFTRAK, HOLD s, the line north of `length` m at `speed`, HOLD/... then disarm."""
        self._until(lambda: self.mode is not None, "send a HEARTBEAT")
        for message in (mavutil.mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED, mavutil.mavlink.MAVLINK_MSG_ID_SIM_STATE,
                        mavutil.mavlink.MAVLINK_MSG_ID_DISTANCE_SENSOR):
            self._ask(message, STICK_RATE)
        self.conn.mav.command_long_send(1, 1, mavutil.mavlink.MAV_CMD_REQUEST_MESSAGE, 0,
                                        mavutil.mavlink.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN, 0, 0, 0, 0, 0, 0)
        self._until(lambda: self.position is not None and self.truth.position is not None, "send its position")
        self._set_mode(ALT_HOLD)
        self._until(lambda: self.mode == ALT_HOLD, "enter ALT_HOLD")
        self._arm(True)
        self._until(lambda: self.armed, "arm")
        self._set_mode(SURFTRAK)
        self._until(lambda: self.mode == SURFTRAK, "enter SURFTRAK")
        start, trim = self.now + HOLD, {"x": 0.0, "y": 0.0, "t": self.now}

        def planned(t: float) -> tuple[float, float]:
            """The line's distance and speed at vehicle time t (a RAMP s ramp up, then `speed` to `length`)."""
            s = t - start
            if s <= 0.0:
                return 0.0, 0.0
            if s < RAMP:
                return speed * s * s / (2 * RAMP), speed * s / RAMP
            return min(speed * (s - RAMP / 2), length), speed if speed * (s - RAMP / 2) < length else 0.0

        def stick(t: float) -> tuple[float, float]:
            """Forward: the speed planned (on the line) or the start held (before it); across: back to the line.
            Each with a trim that settles where the current needs it."""
            x_d, v_d = planned(t)
            self._record(x_d, altitude)
            x, y, _, vx, vy = self.position
            dt, trim["t"] = t - trim["t"], t
            along = v_d - vx if v_d > 0.0 else POSITION_GAIN * (x_d - x) - vx
            trim["x"] += TRIM_GAIN * along * dt
            trim["y"] += LINE_TRIM * -y * dt
            return trim["x"] + SPEED_GAIN * along, trim["y"] - LINE_GAIN * y - LINE_DAMPING * vy

        def coast(t: float) -> tuple[float, float]:
            """Sticks centred at the line's end: the vehicle coasts to a stop."""
            self._record(length, altitude)
            return 0.0, 0.0

        self._fly_for(HOLD + RAMP / 2 + length / speed, stick)
        self._fly_for(3.0, coast)
        self._arm(False)
        self._until(lambda: not self.armed, "disarm")
        self._set_mode(0)

    def _record(self, x_d: float, target: float) -> None:
        truth = self.truth.position if self.truth.position is not None else np.full(3, math.nan)
        height = self.truth.height if self.truth.height is not None else math.nan
        sounding = self.sounding if self.sounding is not None else math.nan
        self.rows.append((self.now, *self.position[:3], *truth, height, sounding, x_d, target))

    def metrics(self) -> dict:
        """`terrain_metrics` of the flight (its samples from SURFTRAK's entry on)."""
        rows = np.array(self.rows)
        t, eta, truth = rows[:, 0], np.zeros((len(rows), 6)), rows[:, 4:7]
        eta[:, :3] = rows[:, 1:4]
        eta_d = np.zeros((len(rows), 6))
        eta_d[:, 0] = rows[:, 9]
        keep = np.concatenate([[True], np.diff(t) > 0])          # one sample per instant
        heights = np.stack([rows[:, 8], rows[:, 7], rows[:, 10]], axis=1)
        return terrain_metrics(t[keep], eta[keep], eta_d[keep], truth[keep], heights[keep])


def fly_surftrak(port: int, speedup: float, length: float, speed: float, altitude: float, folder: Path) -> dict:
    """The pilot's transect on the vehicle listening on `port`: its terrain figures and the vehicle times it flew
    from and to ("flown"), or {"error": why}."""
    pilot = SurftrakPilot(port, speedup)
    try:
        pilot.fly(length, speed, altitude)
        figures = {**pilot.metrics(), "flown": (pilot.rows[0][0], pilot.rows[-1][0])}
        np.savetxt(folder / "pilot.csv", np.array(pilot.rows), delimiter=",",
                   header="t,x,y,z,north_true,east_true,down_true,height_true,sounding,x_d,target", comments="")
        return figures
    except RuntimeError as error:
        return {"error": str(error)}
    finally:
        pilot.close()
