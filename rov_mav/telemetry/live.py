"""The runner's live Rerun sink: `log_tick` only appends to a bounded buffer; a background thread logs batches.

The control loop pays one append per tick (about a microsecond). Every `period` seconds the thread stacks the
buffered ticks and logs them as columns (Rerun's cost is mostly per call, so batches of ~10 ticks are ~10x cheaper
than logging each tick). When the thread falls behind, ticks beyond `capacity` are dropped and counted. Nothing here
waits for the viewer: one that goes away loses the data, the run goes on, and `close` gives up after a timeout.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from dataclasses import dataclass

import numpy as np
import rerun as rr

from rov_mav.flight.record.tick import TickRecord
from rov_mav.model.vehicle import Vehicle
from rov_mav.telemetry.entities import TickColumns, log_static, send_events, send_ticks
from rov_mav.telemetry.recording import FLUSH_TIMEOUT, finish


@dataclass(frozen=True)
class SinkStats:
    """What logging cost: counts, and seconds per tick in the control loop (call) and in the thread (work)."""

    ticks: int              # log_tick calls
    logged: int             # ticks handed to Rerun
    dropped: int            # ticks dropped because the buffer was full
    errors: int             # batches Rerun refused (the run went on)
    call_per_tick: float    # s, mean time inside log_tick
    work_per_tick: float    # s, mean CPU time of the logging thread per tick logged

    def describe(self, period: float) -> str:
        cost = self.call_per_tick + self.work_per_tick
        return (f"Rerun logging: {self.logged} ticks logged, {self.dropped} dropped, {self.errors} errors; "
                f"{cost * 1e3:.3f} ms per tick ({self.call_per_tick * 1e6:.1f} us in the loop + "
                f"{self.work_per_tick * 1e3:.3f} ms in the background) = {100 * cost / period:.1f} % "
                f"of the {period * 1e3:g} ms period")


class RerunSink:
    """A runner sink (`log_tick`, `log_event`, `close`) that streams to a Rerun recording without blocking."""

    def __init__(self, rec: rr.RecordingStream, vehicle: Vehicle, reference_path: np.ndarray | None = None,
                 period: float = 0.2, capacity: int = 1000, close_timeout: float = FLUSH_TIMEOUT):
        """reference_path: (M, 3) planned positions, drawn once; period: s between batches; capacity: ticks."""
        self._rec, self._vehicle = rec, vehicle
        self._period, self._capacity, self._close_timeout = period, capacity, close_timeout
        self._ticks: deque[TickRecord] = deque()
        self._events: deque[tuple[float, str, str]] = deque()
        self._last_position: np.ndarray | None = None
        self._calls = self._logged = self._dropped = self._errors = 0
        self._call_time = self._work_time = 0.0
        self._stop = threading.Event()
        self._closed = False
        log_static(rec, vehicle, reference_path)
        self._thread = threading.Thread(target=self._run, name="rerun-sink", daemon=True)
        self._thread.start()

    def log_tick(self, record: TickRecord) -> None:
        start = time.perf_counter()
        if len(self._ticks) < self._capacity:
            self._ticks.append(record)
        else:
            self._dropped += 1
        self._calls += 1
        self._call_time += time.perf_counter() - start

    def log_event(self, t: float, text: str, level: str = "INFO") -> None:
        self._events.append((t, text, level))

    def close(self) -> None:
        """Log what is buffered, then hand it to the viewer or file (at most `close_timeout` s); idempotent."""
        if self._closed:
            return
        self._closed = True
        self._stop.set()
        self._thread.join(timeout=self._close_timeout)
        finish(self._rec, self._close_timeout)

    @property
    def stats(self) -> SinkStats:
        return SinkStats(ticks=self._calls, logged=self._logged, dropped=self._dropped, errors=self._errors,
                         call_per_tick=self._call_time / max(self._calls, 1),
                         work_per_tick=self._work_time / max(self._logged, 1))

    def _run(self) -> None:
        while not self._stop.wait(self._period):
            self._drain()
        self._drain()

    def _drain(self) -> None:
        start = time.thread_time()
        ticks = [self._ticks.popleft() for _ in range(len(self._ticks))]
        events = [self._events.popleft() for _ in range(len(self._events))]
        try:
            if ticks:
                self._last_position = send_ticks(self._rec, TickColumns.from_records(ticks), self._vehicle,
                                                 self._last_position)
                self._logged += len(ticks)
            send_events(self._rec, events)
        except Exception:   # a bad batch or a failing recording must never reach the control loop
            self._errors += 1
        self._work_time += time.thread_time() - start
