"""The terminal's view of a run: a live one-line status and the events, as a sink (log_tick, log_event, close).

On a terminal the status line is redrawn in place a few times a second; elsewhere (a pipe, CI) a status line is
printed every `every` vehicle seconds instead. Events always get a line of their own.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from rov_mav.flight.record.tick import TickRecord
from rov_mav.mission.metrics import tracking_errors

REDRAW = 0.2          # wall s between redraws on a terminal


class StatusLine:
    def __init__(self, stream=None, every: float = 10.0):
        self.stream = stream or sys.stdout
        self.live = self.stream.isatty()
        self.every = every
        self._next_wall = 0.0
        self._next_t = -np.inf
        self._drawn = False

    def log_tick(self, r: TickRecord) -> None:
        if self.live:
            now = time.monotonic()
            if now < self._next_wall:
                return
            self._next_wall = now + REDRAW
        elif r.t < self._next_t:
            return
        else:
            self._next_t = r.t + self.every
        self._write(self.format(r), live=self.live)

    @staticmethod
    def format(r: TickRecord) -> str:
        position, _ = tracking_errors(r.eta[None], r.reference[None, :6])
        phase = f"{r.progress:4.0%}" if r.t >= 0 else "lead-in"
        tau_hat = " ".join(f"{v:+.1f}" for v in r.tau_hat)
        return (f"t {r.t:7.1f} s  {phase}  err {position[0] * 100:5.1f} cm  depth {r.eta[2]:5.2f} m  "
                f"tau_hat [{tau_hat}]  link {r.control_rate:3.0f} Hz age {r.telemetry_age * 1e3:4.0f} ms  "
                f"{r.battery_voltage:.1f} V")

    def log_event(self, t: float, text: str, level: str) -> None:
        prefix = "" if level == "info" else f"{level.upper()}: "
        self._write(f"[{t:7.1f}] {prefix}{text}", live=False)

    def close(self) -> None:
        if self._drawn:
            self.stream.write("\n")
            self._drawn = False
        self.stream.flush()

    def _write(self, text: str, live: bool) -> None:
        if self._drawn:
            self.stream.write("\r\033[K")
        self.stream.write(text if live else text + "\n")
        self._drawn = live
        self.stream.flush()
