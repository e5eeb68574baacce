"""What goes where in a Rerun recording: the entity tree, and the columnar logging of a batch of control ticks.

Everything is on the `vehicle_time` timeline (s since the mission started), world frame NED:
    world/                     view coordinates (static)
    world/reference/path       the planned path (static line)
    world/reference/now        the reference point eta_d[:3]
    world/trail                the path flown: one segment per tick, accumulated by the blueprint's time range
    world/vehicle              the pose (translation eta[:3], rotation R(Theta), body frame FRD)
    world/vehicle/hull         a box of the vehicle's size (static)
    world/vehicle/thrust       the eight thrust vectors at their mounting points, f_i e_i scaled by ARROW_SCALE
    pose/{x,y,z,roll,pitch,yaw}      vehicle against reference per DOF (m, deg)
    error/position, error/attitude   eta - eta_d (m, with its norm; deg, wrapped)
    control/sliding            s (m/s, rad/s)
    control/force, control/moment    tau commanded (N; N m)
    disturbance/force, disturbance/moment   tau_hat, and the true tau_d when known (N; N m)
    adaptation/translation, adaptation/rotation   gamma (u, v, w; p, q, r)
    thrusters/thrust, thrusters/pwm  the eight thrusts (N) and PWMs (us)
    link                       telemetry age (ms) and control rate achieved (Hz)
    battery                    voltage (V)
    mission/progress           % of the planned duration
    events                     text log: mode changes, arming, watchdog and limit events, aborts
`rov-mav tune` adds, on the `pso_iteration` timeline:
    tuning/best_cost           best cost after each iteration (the counterpart of Fig. IV-1 (i))
    tuning/k1, tuning/k2       the best particle's gains after each iteration (Fig. IV-1 (ii))
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import rerun as rr

from rov_mav.flight.record.tick import TickRecord
from rov_mav.model import dynamics
from rov_mav.model.vehicle import Vehicle
from rov_mav.units import wrap_angle

TIMELINE = "vehicle_time"
ARROW_SCALE = 0.05    # m of arrow per N of thrust

DOFS = ("x", "y", "z", "roll", "pitch", "yaw")
DOF_UNITS = ("m", "m", "m", "deg", "deg", "deg")
POSE = tuple(f"pose/{d}" for d in DOFS)
POSITION_ERROR, ATTITUDE_ERROR = "error/position", "error/attitude"
SLIDING, FORCE, MOMENT = "control/sliding", "control/force", "control/moment"
DISTURBANCE_FORCE, DISTURBANCE_MOMENT = "disturbance/force", "disturbance/moment"
GAMMA_TRANSLATION, GAMMA_ROTATION = "adaptation/translation", "adaptation/rotation"
THRUST, PWM = "thrusters/thrust", "thrusters/pwm"
LINK, BATTERY, PROGRESS, EVENTS = "link", "battery", "mission/progress", "events"
VEHICLE, HULL, ARROWS = "world/vehicle", "world/vehicle/hull", "world/vehicle/thrust"
REFERENCE_PATH, REFERENCE_NOW, TRAIL = "world/reference/path", "world/reference/now", "world/trail"
ARDUSUB_ERRORS = "ardusub/error"    # + "/<target>": ArduSub's own controllers against their logged targets
PSO_TIMELINE = "pso_iteration"
BEST_COST, BEST_K1, BEST_K2 = "tuning/best_cost", "tuning/k1", "tuning/k2"

RED, GREEN, BLUE = (230, 75, 60), (80, 190, 80), (70, 130, 240)
HULL_COLOR = (40, 110, 220, 150)
TRAIL_COLOR = (255, 160, 30)
REFERENCE_COLOR = (170, 170, 170)
THRUSTER_NAMES = [f"T{i}" for i in range(1, 9)]
PALETTE = [(31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189), (140, 86, 75),
           (227, 119, 194), (188, 189, 34)]   # matplotlib's tab10: eight that tell apart

ESTIMATE_WIDTHS = [2.5, 2.5, 2.5, 1.0, 1.0, 1.0]   # estimates bold, the truth thin in the same colour
SERIES = {   # entity -> (names, colours)
    **{p: (["vehicle", "reference"], [TRAIL_COLOR, REFERENCE_COLOR]) for p in POSE},
    POSITION_ERROR: (["x", "y", "z", "norm"], [RED, GREEN, BLUE, (230, 230, 230)]),
    ATTITUDE_ERROR: (["roll", "pitch", "yaw"], [RED, GREEN, BLUE]),
    SLIDING: (list(DOFS), PALETTE[:6]),
    FORCE: (["X", "Y", "Z"], [RED, GREEN, BLUE]),
    MOMENT: (["K", "M", "N"], [RED, GREEN, BLUE]),
    DISTURBANCE_FORCE: (["X est", "Y est", "Z est", "X true", "Y true", "Z true"], [RED, GREEN, BLUE] * 2),
    DISTURBANCE_MOMENT: (["K est", "M est", "N est", "K true", "M true", "N true"], [RED, GREEN, BLUE] * 2),
    GAMMA_TRANSLATION: (["u", "v", "w"], [RED, GREEN, BLUE]),
    GAMMA_ROTATION: (["p", "q", "r"], [RED, GREEN, BLUE]),
    THRUST: (THRUSTER_NAMES, PALETTE),
    PWM: (THRUSTER_NAMES, PALETTE),
    LINK: (["telemetry age (ms)", "control rate (Hz)"], [TRAIL_COLOR, BLUE]),
    BATTERY: (["voltage (V)"], [GREEN]),
    PROGRESS: (["progress (%)"], [BLUE]),
}


@dataclass(frozen=True)
class TickColumns:
    """n control ticks stacked: the fields of `TickRecord` with a leading (n,) axis; None where not known (a
    reviewed log of a dive rov-mav did not fly has no reference or controller internals)."""

    t: np.ndarray                     # (n,)
    eta: np.ndarray                   # (n, 6)
    reference: np.ndarray | None      # (n, >= 6), eta_d first
    tau: np.ndarray | None            # (n, 6)
    tau_hat: np.ndarray | None        # (n, 6)
    s: np.ndarray | None              # (n, 6)
    gamma: np.ndarray | None          # (n, 6)
    thrusts: np.ndarray | None = None            # (n, 8)
    pwm: np.ndarray | None = None                # (n, 8)
    true_disturbance: np.ndarray | None = None   # (n, 6)
    progress: np.ndarray | None = None           # (n,) in [0, 1]
    telemetry_age: np.ndarray | None = None      # (n,) s
    control_rate: np.ndarray | None = None       # (n,) Hz
    battery_voltage: np.ndarray | None = None    # (n,) V

    @classmethod
    def from_records(cls, records: Sequence[TickRecord]) -> "TickColumns":
        def stack(name: str) -> np.ndarray:
            return np.array([getattr(r, name) for r in records], dtype=float)

        known = all(r.true_disturbance is not None for r in records)
        return cls(**{name: stack(name) for name in (
            "t", "eta", "reference", "tau", "tau_hat", "s", "gamma", "thrusts", "pwm", "progress",
            "telemetry_age", "control_rate", "battery_voltage")},
            true_disturbance=stack("true_disturbance") if known else None)


def log_static(rec: rr.RecordingStream, vehicle: Vehicle, reference_path: np.ndarray | None) -> None:
    """The parts that do not change: frames, hull, thruster mounts, planned path, series names and colours."""
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_DOWN, static=True)
    rec.log(HULL, rr.Boxes3D(half_sizes=[0.5 * vehicle.size], colors=[HULL_COLOR], fill_mode="solid"), static=True)
    rec.log(ARROWS, rr.Arrows3D.from_fields(origins=vehicle.thruster_positions, colors=[RED], radii=0.01),
            static=True)
    if reference_path is not None:
        rec.log(REFERENCE_PATH, rr.LineStrips3D([reference_path], colors=[REFERENCE_COLOR], radii=0.01),
                static=True)
    rec.log(TRAIL, rr.LineStrips3D.from_fields(colors=[TRAIL_COLOR], radii=0.02), static=True)
    rec.log(REFERENCE_NOW, rr.Points3D.from_fields(colors=[GREEN], radii=0.06), static=True)
    for path, (names, colors) in SERIES.items():
        widths = ESTIMATE_WIDTHS if path in (DISTURBANCE_FORCE, DISTURBANCE_MOMENT) else None
        rec.log(path, rr.SeriesLines(names=names, colors=colors, widths=widths), static=True)


def send_ticks(rec: rr.RecordingStream, ticks: TickColumns, vehicle: Vehicle,
               previous_position: np.ndarray | None = None) -> np.ndarray:
    """Log a batch of ticks as columns; returns the last position, where the next batch's trail starts."""
    n = len(ticks.t)
    index = [rr.TimeColumn(TIMELINE, duration=ticks.t)]

    def send(path: str, columns) -> None:
        rec.send_columns(path, indexes=index, columns=columns)
        time.sleep(0)   # hand the GIL to a waiting control loop between calls (measured: p99 wake-up 4 -> 0.6 ms)

    def scalars(path: str, values: np.ndarray) -> None:
        values = np.asarray(values, dtype=float).reshape(n, -1)
        send(path, rr.Scalars.columns(scalars=values.ravel()).partition(np.full(n, values.shape[1])))

    position = ticks.eta[:, :3]
    start = position[:1] if previous_position is None else np.asarray(previous_position)[None]
    send(VEHICLE, rr.Transform3D.columns(translation=position, mat3x3=dynamics.rotation(ticks.eta)))
    send(TRAIL, rr.LineStrips3D.columns(strips=np.stack([np.concatenate([start, position[:-1]]), position], 1)))
    if ticks.reference is not None:
        eta_d = ticks.reference[:, :6]
        send(REFERENCE_NOW, rr.Points3D.columns(positions=eta_d[:, :3]))
        error = ticks.eta - eta_d
        error[:, 3:] = np.degrees(wrap_angle(error[:, 3:]))
        shown = np.concatenate([position, np.degrees(eta_d[:, 3:]) + error[:, 3:]], axis=1)  # angles unwrapped
        reference = np.concatenate([eta_d[:, :3], np.degrees(eta_d[:, 3:])], axis=1)
        for i, path in enumerate(POSE):
            scalars(path, np.stack([shown[:, i], reference[:, i]], axis=1))
        scalars(POSITION_ERROR, np.concatenate([error[:, :3], np.linalg.norm(error[:, :3], axis=1)[:, None]], 1))
        scalars(ATTITUDE_ERROR, error[:, 3:])
    else:
        shown = np.concatenate([position, np.degrees(np.unwrap(ticks.eta[:, 3:], axis=0))], axis=1)
        for i, path in enumerate(POSE):
            scalars(path, shown[:, i])
    if ticks.s is not None:
        scalars(SLIDING, ticks.s)
    if ticks.tau is not None:
        scalars(FORCE, ticks.tau[:, :3])
        scalars(MOMENT, ticks.tau[:, 3:])
    truth = ticks.true_disturbance
    if ticks.tau_hat is not None:
        for path, part in ((DISTURBANCE_FORCE, slice(0, 3)), (DISTURBANCE_MOMENT, slice(3, 6))):
            estimate = ticks.tau_hat[:, part]
            scalars(path, estimate if truth is None else np.hstack([estimate, truth[:, part]]))
    if ticks.gamma is not None:
        scalars(GAMMA_TRANSLATION, ticks.gamma[:, :3])
        scalars(GAMMA_ROTATION, ticks.gamma[:, 3:])
    if ticks.thrusts is not None:
        vectors = ARROW_SCALE * ticks.thrusts[:, :, None] * vehicle.thruster_directions[None]
        send(ARROWS, rr.Arrows3D.columns(vectors=vectors.reshape(-1, 3)).partition(np.full(n, 8)))
        scalars(THRUST, ticks.thrusts)
    if ticks.pwm is not None:
        scalars(PWM, ticks.pwm)
    if ticks.telemetry_age is not None and ticks.control_rate is not None:
        scalars(LINK, np.stack([1e3 * ticks.telemetry_age, ticks.control_rate], axis=1))
    if ticks.battery_voltage is not None:
        scalars(BATTERY, ticks.battery_voltage)
    if ticks.progress is not None:
        scalars(PROGRESS, 100.0 * ticks.progress)
    return position[-1].copy()


def send_events(rec: rr.RecordingStream, events: Sequence[tuple[float, str, str]]) -> None:
    """Log (t, text, level) events to the text log; level as `logging` names it (INFO, WARNING, ERROR, ...)."""
    if not events:
        return
    t, text, level = zip(*events)
    levels = ["WARN" if lv.upper() == "WARNING" else lv.upper() for lv in level]
    rec.send_columns(EVENTS, indexes=[rr.TimeColumn(TIMELINE, duration=np.array(t, dtype=float))],
                     columns=rr.TextLog.columns(text=list(text), level=levels))


def send_target_errors(rec: rr.RecordingStream, series: dict[str, tuple[np.ndarray, np.ndarray]]) -> None:
    """ArduSub's error to each target it logged, where its mode held it: name -> (t, error), one entity each under
    ARDUSUB_ERRORS (`review.controller_tracking`)."""
    for name, (t, error) in series.items():
        rec.send_columns(f"{ARDUSUB_ERRORS}/{name}", indexes=[rr.TimeColumn(TIMELINE, duration=np.asarray(t, float))],
                         columns=rr.Scalars.columns(scalars=np.asarray(error, dtype=float)))


def send_convergence(rec: rr.RecordingStream, cost_history: np.ndarray, gain_history: np.ndarray) -> None:
    """PSO convergence on the `pso_iteration` timeline: best cost (I,) and the best gains (I, 12) per iteration."""
    index = [rr.TimeColumn(PSO_TIMELINE, sequence=np.arange(1, len(cost_history) + 1))]
    rec.log(BEST_COST, rr.SeriesLines(names=["best cost"]), static=True)
    rec.send_columns(BEST_COST, indexes=index, columns=rr.Scalars.columns(scalars=np.asarray(cost_history, float)))
    for path, part in ((BEST_K1, slice(0, 6)), (BEST_K2, slice(6, 12))):
        values = np.asarray(gain_history, float)[:, part]
        rec.log(path, rr.SeriesLines(names=list(DOFS), colors=PALETTE[:6]), static=True)
        rec.send_columns(path, indexes=index,
                         columns=rr.Scalars.columns(scalars=values.ravel()).partition(np.full(len(values), 6)))
