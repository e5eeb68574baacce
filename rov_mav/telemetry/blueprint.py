"""The default Rerun layout: the 3D scene large with the event log under it, the plots beside it in tabs."""

from __future__ import annotations

import numpy as np
import rerun.blueprint as rrb

from rov_mav.telemetry import entities as e


def _plot(path: str, name: str) -> rrb.TimeSeriesView:
    """A plot of the whole run (Rerun's default is a window around the time cursor)."""
    whole = rrb.TimeRange(start=rrb.TimeRangeBoundary.infinite(), end=rrb.TimeRangeBoundary.infinite())
    return rrb.TimeSeriesView(origin=path, name=name, axis_x=rrb.TimeAxis(view_range=whole))


def _eye(path: np.ndarray) -> rrb.EyeControls3D:
    """An orbit camera above and behind the path's start corner, taking in the whole path; (M, 3) NED."""
    low, high = path.min(axis=0), path.max(axis=0)
    centre, extent = 0.5 * (low + high), max(float(np.max(high - low)), 2.0)
    return rrb.EyeControls3D(position=centre + extent * np.array([-0.9, -0.5, -0.8]), look_target=centre,
                             eye_up=[0.0, 0.0, -1.0])


def default_blueprint(reference_path: np.ndarray | None = None, tuning: bool = False,
                      ardusub_targets: bool = False) -> rrb.Blueprint:
    """3D view and events | tabs: tracking, pose, control, thrusters, link (and PSO convergence first, for `tune`;
    ArduSub's own errors to its targets in the tracking tab, for a reviewed dive that logged them).

    The camera frames `reference_path`."""
    whole_run = rrb.VisibleTimeRanges(rrb.VisibleTimeRange(
        e.TIMELINE, start=rrb.TimeRangeBoundary.infinite(), end=rrb.TimeRangeBoundary.cursor_relative()))
    scene = rrb.Spatial3DView(origin="world", name="Vehicle (NED)", overrides={e.TRAIL: whole_run},
                              eye_controls=None if reference_path is None else _eye(reference_path))
    tracking = rrb.Vertical(
        _plot(e.POSITION_ERROR, "Position error (m)"),
        _plot(e.ATTITUDE_ERROR, "Attitude error (deg)"),
        _plot(e.DISTURBANCE_FORCE, "Disturbance force: estimate vs true (N)"),
        _plot(e.DISTURBANCE_MOMENT, "Disturbance moment: estimate vs true (N m)"),
        *([_plot(e.ARDUSUB_ERRORS, "ArduSub's own control: error to its logged targets (m, m/s, deg)")]
          if ardusub_targets else []),
        name="Tracking")
    pose = rrb.Grid(*(_plot(path, f"{dof} ({unit})") for path, dof, unit in zip(e.POSE, e.DOFS, e.DOF_UNITS)),
                    grid_columns=2, name="Pose vs reference")
    control = rrb.Vertical(
        _plot(e.SLIDING, "Sliding variable s"),
        _plot(e.FORCE, "Commanded force (N)"),
        _plot(e.MOMENT, "Commanded moment (N m)"),
        _plot(e.GAMMA_TRANSLATION, "Adaptation rate, translation"),
        _plot(e.GAMMA_ROTATION, "Adaptation rate, rotation"),
        name="Control")
    thrusters = rrb.Vertical(_plot(e.THRUST, "Thrust (N)"), _plot(e.PWM, "PWM (us)"), name="Thrusters")
    link = rrb.Vertical(_plot(e.LINK, "Link"), _plot(e.BATTERY, "Battery (V)"),
                        _plot(e.PROGRESS, "Mission progress (%)"), name="Link")
    tabs = [tracking, pose, control, thrusters, link]
    if tuning:
        tabs.insert(0, rrb.Vertical(_plot(e.BEST_COST, "Best cost"), _plot(e.BEST_K1, "Best k1"),
                                    _plot(e.BEST_K2, "Best k2"), name=f"PSO (timeline {e.PSO_TIMELINE})"))
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(scene, rrb.TextLogView(origin=e.EVENTS, name="Events"), row_shares=[4, 1]),
            rrb.Tabs(*tabs, active_tab=0),
            column_shares=[3, 2]),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(state="collapsed"),
    )
