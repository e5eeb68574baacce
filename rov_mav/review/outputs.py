"""A reviewed dive shown as `simulate` shows a run: the same figures (plus the thrusters' PWM and a timeline of the
link, battery and depth), and a Rerun recording with the same entities and layout, and the events in its log."""

from __future__ import annotations

from pathlib import Path

import rerun as rr

from rov_mav.model.vehicle import Vehicle
from rov_mav.offline.plots import plot_dofs, plot_estimates, plot_path, plot_rates, plot_thrusters, plot_timeline
from rov_mav.review.dive_review import DiveReview
from rov_mav.telemetry.entities import log_static, send_events, send_target_errors, send_ticks


def write_figures(review: DiveReview, out_dir: Path) -> list[Path]:
    """The figures there is data for, written to out_dir; their paths."""
    out_dir.mkdir(parents=True, exist_ok=True)
    label = review.label
    paths = []
    if review.trace is not None:
        paths.append(plot_dofs(review.trace, f"{label}: tracking per DOF", out_dir / "dofs.png"))
        paths.append(plot_path({label: review.trace}, f"{label}: 3D path", out_dir / "path3d.png",
                               planned=review.planned))
        if review.internals:
            paths.append(plot_estimates(review.trace, f"{label}: disturbance estimate", out_dir / "estimates.png"))
            paths.append(plot_rates(review.trace, f"{label}: adaptation rates", out_dir / "rates.png"))
    if review.thrusters:
        paths.append(plot_thrusters(review.thrusters, review.limits, f"{label}: thrusters", out_dir / "thrusters.png"))
    if review.timeline:
        paths.append(plot_timeline(review.timeline, f"{label}: link, battery, depth", out_dir / "timeline.png",
                                   review.marks))
    return paths


def record(review: DiveReview, rec: rr.RecordingStream, vehicle: Vehicle) -> None:
    """The whole dive into an open recording: static scene, every state as a tick, the events."""
    log_static(rec, vehicle, review.reference_path)
    if review.columns is not None:
        send_ticks(rec, review.columns, vehicle)
    send_events(rec, review.events)
    send_target_errors(rec, review.targets)
