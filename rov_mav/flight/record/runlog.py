"""The run log (`--log DIR`): ticks.csv (state, reference, commands, the controller's internals), events.csv, the
raw MAVLink traffic both ways as mavlink.tlog (pymavlink's logfile format: 8-byte big-endian microseconds
since the epoch, then the packet; open it with `mavutil.mavlink_connection(path)` or MAVExplorer), and run.json
(what was flown: mission, controller, rate, the disturbance when known).

Every run also says on the link when its mission starts, in vehicle time (`mission_start_text`, a STATUSTEXT that
ArduSub writes to its own log as "GCS:..."), so that any telemetry log of the dive can be aligned with the mission.

The loop only queues; a writer thread formats and writes, so logging never blocks a control tick.
"""

from __future__ import annotations

import csv
import json
import queue
import re
import struct
import threading
import time
from pathlib import Path

import numpy as np

from rov_mav.flight.record.tick import TickRecord

DOF = ("x", "y", "z", "phi", "theta", "psi")
BODY = ("u", "v", "w", "p", "q", "r")
WRENCH = ("X", "Y", "Z", "K", "M", "N")
# ticks.csv's column groups, by name: what `review.logdir.column_block` reads back (analyze, identify)
REFERENCE = tuple(f"{d}{suffix}" for suffix in ("_d", "_dot_d", "_ddot_d") for d in DOF)
THRUSTS = tuple(f"thrust_{i}" for i in range(1, 9))
PWMS = tuple(f"pwm_{i}" for i in range(1, 9))
TRUTH = ("x_true", "y_true", "z_true")     # where a simulator says the vehicle really is (empty on a real one)
REPORTED = ("x_vehicle", "y_vehicle", "z_vehicle")   # the vehicle's own estimate (x, y, z: the one the law flew on)


def per_wrench(name: str) -> tuple[str, ...]:
    """The six columns of a body wrench: tau_X ... tau_N."""
    return tuple(f"{name}_{w}" for w in WRENCH)


def per_dof(name: str) -> tuple[str, ...]:
    """The six columns of a per-DOF quantity: s_x ... s_psi."""
    return tuple(f"{name}_{d}" for d in DOF)


COLUMNS = ("t", "vehicle_time", "progress", *DOF, *BODY, *REFERENCE, *per_wrench("tau"), *per_wrench("tau_hat"),
           *per_dof("s"), *per_dof("gamma"), *THRUSTS, *PWMS, "telemetry_age", "latency", "control_rate",
           "battery_voltage", "horizon", *TRUTH, *REPORTED, "height", "height_true", "surface_depth")
RUN_INFO = "run.json"
_STOP = object()
_MISSION_START = re.compile(r"rov-mav: mission t0 = (\d+(?:\.\d+)?) s since boot")


def mission_start_text(t0: float) -> str:
    """The STATUSTEXT announcing that the mission (t = 0) starts at `t0` vehicle s since boot (< 50 characters)."""
    return f"rov-mav: mission t0 = {t0:.3f} s since boot"


def parse_mission_start(text: str) -> float | None:
    """t0 from a `mission_start_text` (as ArduSub logs it, with a prefix, too), else None."""
    found = _MISSION_START.search(text)
    return float(found.group(1)) if found else None


def tick_row(r: TickRecord) -> list[str]:
    """One ticks.csv row: the times as exactly as the run held them (its metrics' windows are read back from them),
    every other value to 9 significant digits."""
    times = [repr(float(r.t)), repr(float(r.vehicle_time))]
    values = [r.progress, *r.eta, *r.nu, *r.reference, *r.tau, *r.tau_hat, *r.s, *r.gamma, *r.thrusts,
              *r.pwm, r.telemetry_age, r.latency, r.control_rate, r.battery_voltage, r.horizon,
              *(r.truth if r.truth is not None else (np.nan,) * 3),
              *(r.reported if r.reported is not None else r.eta[:3]), r.height, r.height_true, r.surface]
    return times + [f"{float(v):.9g}" for v in values]


class RunLog:
    """A sink (log_tick, log_event, close) plus `log_mavlink(msg, outgoing)` for a session's taps."""

    def __init__(self, directory: str | Path):
        self.directory = Path(directory)
        self.directory.mkdir(parents=True, exist_ok=True)
        self._queue: queue.SimpleQueue = queue.SimpleQueue()
        self._thread = threading.Thread(target=self._write, name="run-log", daemon=True)
        self._thread.start()

    def write_run_info(self, info: dict) -> None:
        """run.json: what this run flies (written at once, before the loop starts)."""
        (self.directory / RUN_INFO).write_text(json.dumps(info, indent=2) + "\n")

    def log_tick(self, record: TickRecord) -> None:
        self._queue.put(("tick", record))

    def log_event(self, t: float, text: str, level: str) -> None:
        self._queue.put(("event", (t, level, text)))

    def log_mavlink(self, msg, _outgoing: bool) -> None:
        self._queue.put(("mavlink", (time.time(), msg.get_msgbuf())))

    def close(self) -> None:
        self._queue.put(_STOP)
        self._thread.join()

    def _write(self) -> None:
        with open(self.directory / "ticks.csv", "w", newline="") as ticks_file, \
                open(self.directory / "events.csv", "w", newline="") as events_file, \
                open(self.directory / "mavlink.tlog", "wb") as tlog:
            ticks, events = csv.writer(ticks_file), csv.writer(events_file)
            ticks.writerow(COLUMNS)
            events.writerow(["t", "level", "text"])
            while (item := self._queue.get()) is not _STOP:
                kind, payload = item
                if kind == "tick":
                    ticks.writerow(tick_row(payload))
                elif kind == "event":
                    events.writerow([f"{payload[0]:.3f}", payload[1], payload[2]])
                else:
                    wall, packet = payload
                    tlog.write(struct.pack(">Q", int(wall * 1e6) & ~3) + bytes(packet))
