"""An offline run (`simulate`'s Trace) logged to Rerun in one go, as columns on the `vehicle_time` timeline."""

from __future__ import annotations

import math

import numpy as np
import rerun as rr

from rov_mav.mission.missions import Mission
from rov_mav.model.thrusters import Allocator, thrusts_to_pwms
from rov_mav.model.vehicle import Vehicle
from rov_mav.offline.simulation import Trace
from rov_mav.telemetry.entities import TickColumns, log_static, send_events, send_ticks

NOMINAL_VOLTAGE = 16.0   # V: a charged 4S pack, for the thrusts and PWMs shown (simulate's plant takes tau directly)


def trace_columns(trace: Trace, vehicle: Vehicle, voltage: float = NOMINAL_VOLTAGE) -> TickColumns:
    """The trace as ticks, with the thrusts and PWMs the runner would command for its tau at `voltage`."""
    thrusts, _ = Allocator.for_vehicle(vehicle, voltage).thrusts(trace.tau)
    truth = None if trace.true_disturbance is None else np.broadcast_to(trace.true_disturbance, trace.tau.shape)
    return TickColumns(t=trace.t, eta=trace.eta, reference=trace.reference, tau=trace.tau, tau_hat=trace.tau_hat,
                       s=trace.s, gamma=trace.gamma, thrusts=thrusts, pwm=thrusts_to_pwms(thrusts, voltage),
                       true_disturbance=truth)


def _describe(entry) -> str:
    fields = entry.model_dump(exclude_none=True, exclude_defaults=True)
    return ", ".join(f"{k} {math.degrees(v):g} deg" if k == "heading" else f"{k} {v}" for k, v in fields.items())


def mission_events(mission: Mission, trace: Trace) -> list[tuple[float, str, str]]:
    """(t, text, level): the start of each path segment reached, and how the run ended."""
    end = float(trace.t[-1])
    events = [(seg.t0, f"path[{i}]: {_describe(entry)}", "INFO")
              for i, (seg, entry) in enumerate(zip(mission.segments, mission.spec.path)) if seg.t0 <= end]
    events.append((end, "run completed", "INFO") if trace.completed else (end, "run DIVERGED", "ERROR"))
    return events


def log_trace(rec: rr.RecordingStream, trace: Trace, vehicle: Vehicle,
              events: list[tuple[float, str, str]] = ()) -> None:
    """Log a whole run: static scene, every tick, and the events."""
    log_static(rec, vehicle, trace.reference[:, :3])
    send_ticks(rec, trace_columns(trace, vehicle), vehicle)
    send_events(rec, events)
