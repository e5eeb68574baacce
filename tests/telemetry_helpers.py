"""Shared by the telemetry tests: runner-like tick records from a simulated run, and reading a .rrd back."""

from __future__ import annotations

import socket
import time
from pathlib import Path

import numpy as np
import pyarrow as pa
from rerun.chunk import RrdReader

from rov_mav.flight.record.tick import TickRecord
from rov_mav.model.vehicle import Vehicle
from rov_mav.offline.simulation import Trace
from rov_mav.telemetry import TIMELINE, trace_columns


def tick_records(trace: Trace, vehicle: Vehicle, t0: float = 0.0) -> list[TickRecord]:
    """One TickRecord per sample of `trace`, as the runner would build them, starting at vehicle time t0."""
    c = trace_columns(trace, vehicle)
    n = len(c.t)
    return [TickRecord(t=t0 + c.t[k], vehicle_time=t0 + c.t[k], eta=c.eta[k], nu=trace.nu[k], reference=c.reference[k], tau=c.tau[k],
                       tau_hat=c.tau_hat[k], s=c.s[k], gamma=c.gamma[k], thrusts=c.thrusts[k], pwm=c.pwm[k],
                       progress=k / (n - 1), telemetry_age=0.004 + 1e-5 * k, latency=0.001, control_rate=50.0,
                       battery_voltage=16.0 - 1e-3 * k, true_disturbance=trace.true_disturbance)
            for k in range(n)]


def temporal_entities(rrd: Path) -> set[str]:
    return {c.entity_path for c in RrdReader(rrd).stream().filter(is_static=False).to_chunks()}


def read_column(rrd: Path, entity: str, component: str) -> tuple[np.ndarray, list]:
    """(times in s, values) of one component of one entity, in time order."""
    chunks = RrdReader(rrd).stream().filter(content=entity, is_static=False, components=component).to_chunks()
    batches = [c.to_record_batch() for c in chunks]
    t = np.concatenate([b.column(TIMELINE).cast(pa.int64()).to_numpy() for b in batches]) * 1e-9
    values = [v for b in batches for v in b.column(component).to_pylist()]
    order = np.argsort(t, kind="stable")
    return t[order], [values[i] for i in order]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_listening(port: int, timeout: float) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        with socket.socket() as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                return
        time.sleep(0.1)
    raise TimeoutError(f"nothing listening on port {port} after {timeout} s")
