"""A station on an ArduSub SITL for tools/sitl_square.py: a truth monitor beside the flight (`rov-mav run`, with a law
of ours or `--controller ardusub-guided`).

`Monitor` (sysid 200, neither drives nor masks a GCS) records, on its own link, ATTITUDE, LOCAL_POSITION_NED and
SIM_STATE at one rate. ArduPilot sends messages of the same interval in one burst of one scheduler pass, in that
order (ATTITUDE, SIM_STATE, LOCAL_POSITION_NED: measured), so a SIM_STATE (which has no timestamp) takes the
time_boot_ms of the ATTITUDE before it, and the LOCAL_POSITION_NED with that time_boot_ms is the estimate at the
same instant. SIM_STATE's lat_int/lon_int (1e-7 deg, ~1 cm) and alt become NED about GPS_GLOBAL_ORIGIN, the
EKF's origin, with ArduPilot's flat-earth scaling (Location::get_distance_NE).
"""

from __future__ import annotations

import threading
import time

import numpy as np
from pymavlink import mavutil


mavlink = mavutil.mavlink
LATLON_TO_M = 0.011131884502145034      # m per 1e-7 deg of latitude (ArduPilot's LOCATION_SCALING_FACTOR)
MONITOR_SYSID = 200
CONNECT_WAIT = 30.0                     # wall s


def set_interval(conn, msg_id: int, hz: float) -> None:
    """SET_MESSAGE_INTERVAL on this link (ArduPilot keeps one schedule per link); hz <= 0 stops the message."""
    interval = 1e6 / hz if hz > 0 else -1
    conn.mav.command_long_send(1, 1, mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 0, msg_id, interval, 0, 0, 0, 0, 0)


class Monitor(threading.Thread):
    """Records the estimate and SITL's truth at `rate` Hz until `stop()`; `samples()` pairs them."""

    def __init__(self, port: int, rate: float = 25.0):
        super().__init__(daemon=True)
        self.conn = mavutil.mavlink_connection(f"tcp:127.0.0.1:{port}", source_system=MONITOR_SYSID,
                                               source_component=190)
        self.conn.wait_heartbeat(timeout=CONNECT_WAIT)
        self.rate = rate
        self.origin = None                  # GPS_GLOBAL_ORIGIN
        self.attitude: dict[int, tuple] = {}
        self.position: dict[int, tuple] = {}
        self.truth: dict[int, tuple] = {}
        self.clock: list[tuple[int, float]] = []     # (time_boot_ms, wall) of every ATTITUDE
        self.voltage: float | None = None
        self.texts: list[str] = []
        self._last_attitude_ms: int | None = None
        self._stopped = threading.Event()
        for name in ("ATTITUDE", "LOCAL_POSITION_NED", "SIM_STATE"):
            set_interval(self.conn, getattr(mavlink, f"MAVLINK_MSG_ID_{name}"), rate)

    def run(self) -> None:
        next_origin_request = 0.0
        while not self._stopped.is_set():
            if self.origin is None and time.monotonic() >= next_origin_request:
                next_origin_request = time.monotonic() + 1.0
                self.conn.mav.command_long_send(1, 1, mavlink.MAV_CMD_REQUEST_MESSAGE, 0,
                                                mavlink.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN, 0, 0, 0, 0, 0, 0)
            try:
                msg = self.conn.recv_match(blocking=True, timeout=0.2)
            except (OSError, ValueError):
                return
            if msg is not None and msg.get_srcSystem() == 1:
                self._take(msg)

    def _take(self, msg) -> None:
        kind = msg.get_type()
        if kind == "ATTITUDE":
            self._last_attitude_ms = msg.time_boot_ms
            self.attitude[msg.time_boot_ms] = (msg.roll, msg.pitch, msg.yaw)
            self.clock.append((msg.time_boot_ms, time.perf_counter()))
        elif kind == "LOCAL_POSITION_NED":
            self.position[msg.time_boot_ms] = (msg.x, msg.y, msg.z)
        elif kind == "SIM_STATE" and self._last_attitude_ms is not None:
            self.truth[self._last_attitude_ms] = (msg.lat_int, msg.lon_int, msg.alt, msg.roll, msg.pitch, msg.yaw)
        elif kind == "GPS_GLOBAL_ORIGIN":
            self.origin = msg
        elif kind == "SYS_STATUS" and msg.voltage_battery not in (0, 0xFFFF):
            self.voltage = msg.voltage_battery / 1000.0
        elif kind == "STATUSTEXT":
            self.texts.append(msg.text)

    def wait_for_position(self, timeout: float) -> None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.position and self.origin is not None:
                return
            time.sleep(0.2)
        raise RuntimeError(f"SITL gave no EKF position and origin within {timeout:g} s")

    def stop(self) -> None:
        """Streams off, then a clean close (a client that stops reading can leave SITL blocked on its queue)."""
        for name in ("ATTITUDE", "LOCAL_POSITION_NED", "SIM_STATE"):
            set_interval(self.conn, getattr(mavlink, f"MAVLINK_MSG_ID_{name}"), 0.0)
        self._stopped.set()
        self.join(2.0)
        self.conn.close()

    def samples(self) -> dict[str, np.ndarray]:
        """Paired samples: t (N,) vehicle s; ekf (N, 6) and truth (N, 6) poses [x, y, z NED about the EKF origin,
        roll, pitch, yaw]."""
        keys = sorted(set(self.truth) & set(self.position) & set(self.attitude))
        lat0 = self.origin.latitude
        lon0 = self.origin.longitude
        alt0 = self.origin.altitude / 1000.0
        truth = np.array([self.truth[k] for k in keys], dtype=float).reshape(-1, 6)
        lat, lon = truth[:, 0], truth[:, 1]
        scale = np.cos(np.radians((lat + lat0) / 2 * 1e-7))
        ned = np.column_stack([(lat - lat0) * LATLON_TO_M, (lon - lon0) * LATLON_TO_M * scale, -(truth[:, 2] - alt0)])
        ekf = np.column_stack([np.array([self.position[k] for k in keys]).reshape(-1, 3),
                               np.array([self.attitude[k] for k in keys]).reshape(-1, 3)])
        return {"t": np.array(keys, dtype=float) / 1000.0, "ekf": ekf,
                "truth": np.column_stack([ned, truth[:, 3:]])}

    def speed(self, since_ms: int = 0) -> tuple[float, float]:
        """(mean, lowest over 10 wall s windows) of vehicle s per wall s since `since_ms`."""
        c = np.array([(ms, w) for ms, w in self.clock if ms >= since_ms], dtype=float)
        if len(c) < 2:
            return float("nan"), float("nan")
        mean = (c[-1, 0] - c[0, 0]) / 1000.0 / (c[-1, 1] - c[0, 1])
        edges = np.arange(c[0, 1], c[-1, 1], 10.0)
        idx = np.searchsorted(c[:, 1], edges)
        windows = [(c[j, 0] - c[i, 0]) / 1000.0 / (c[j, 1] - c[i, 1]) for i, j in zip(idx[:-1], idx[1:]) if j > i]
        return mean, min(windows) if windows else mean
