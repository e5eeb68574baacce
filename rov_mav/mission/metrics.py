"""Tracking metrics of a run, from its time series (the same JSON for `simulate` and `run`)."""

from __future__ import annotations

import numpy as np

from rov_mav.control.law import tracking_error


def truth_metrics(truth: np.ndarray, eta_d: np.ndarray, estimate: np.ndarray | None = None,
                  reported: np.ndarray | None = None) -> dict:
    """RMS and max position error against the truth (a simulator's SIM_STATE), over the samples that have it; {} when
    none does (a real vehicle). With `estimate` (the position the law flew on) and `reported` (the vehicle's own
    estimate), each estimate's own RMS error against the truth too. truth, estimate, reported (N, 3), eta_d (N, 6)."""
    known = np.all(np.isfinite(truth), axis=1)
    if not known.any():
        return {}
    error = np.linalg.norm(truth[known] - eta_d[known, :3], axis=1)
    out = {"rms_position_error_truth_m": _rms(error), "max_position_error_truth_m": float(error.max()),
           "truth_samples": int(known.sum())}
    for name, position in (("estimate", estimate), ("vehicle_estimate", reported)):
        if position is not None:
            out[f"rms_{name}_error_truth_m"] = _rms(np.linalg.norm(truth[known] - position[known, :3], axis=1))
    return out


STRIKE_HEIGHT = 0.3              # m: a height under this is a bottom (or ice) strike
MOVING = 0.05                    # m/s: the planned speed above which a leg's line has a direction


def terrain_metrics(t: np.ndarray, eta: np.ndarray, eta_d: np.ndarray, truth: np.ndarray, heights: np.ndarray) -> dict:
    """Altitude and standoff legs: the height held against the leg's own (by the sounder, and by the truth where a
    simulator says it), strikes (episodes under STRIKE_HEIGHT, by the truth when known, else by the sounder), and
    where the plan moves, the cross-track error (horizontal distance off the planned line, of the estimate flown on
    and of the truth) and the speed along the line less the planned speed. t (N,), eta, eta_d (N, 6), truth (N, 3),
    heights (N, 3): sounder, true, target (NaN off the legs)."""
    measured, true, target = heights.T
    leg = np.isfinite(target)
    if not leg.any():
        return {}
    out = {"samples": int(leg.sum())}
    seen = leg & np.isfinite(measured)
    out["rms_height_error_sounder_m"] = _rms(measured[seen] - target[seen])
    known = leg & np.isfinite(true)
    if known.any():
        out["rms_height_error_true_m"] = _rms(true[known] - target[known])
        out["max_height_error_true_m"] = float(np.abs(true[known] - target[known]).max())
        out["min_height_true_m"] = float(true[known].min())
    low = np.where(known, true, measured)[leg] < STRIKE_HEIGHT
    out["strikes"] = int(np.sum(low[1:] & ~low[:-1]) + (low[0] if low.size else 0))
    if t.size > 2:
        planned = np.gradient(eta_d[:, :2], t, axis=0)
        speed = np.linalg.norm(planned, axis=1)
        moving = leg & (speed > MOVING)
        if moving.any():
            along = planned[moving] / speed[moving, None]
            across = np.stack([-along[:, 1], along[:, 0]], axis=1)
            out["rms_cross_track_m"] = _rms(np.sum((eta[moving, :2] - eta_d[moving, :2]) * across, axis=1))
            truly = np.all(np.isfinite(truth[moving, :2]), axis=1)
            if truly.any():
                off = np.sum((truth[moving, :2] - eta_d[moving, :2]) * across, axis=1)[truly]
                out["rms_cross_track_true_m"] = _rms(off)
            flown = np.sum(np.gradient(eta[:, :2], t, axis=0)[moving] * along, axis=1)
            out["rms_speed_error_m_s"] = _rms(flown - speed[moving])
    return out


def tracking_errors(eta: np.ndarray, eta_d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Position error norm (m) and attitude error norm (rad, angles wrapped) per sample; (N, 6) -> (N,), (N,)."""
    e = tracking_error(eta, eta_d)
    return np.linalg.norm(e[:, :3], axis=1), np.linalg.norm(e[:, 3:], axis=1)


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x**2))) if x.size else float("nan")


def run_metrics(mission: str, controller: str, t: np.ndarray, eta: np.ndarray, eta_d: np.ndarray,
                tau: np.ndarray, tau_hat: np.ndarray, true_disturbance: np.ndarray | None,
                completed: bool) -> dict:
    """The metrics JSON: RMS and max errors, steady-state errors over the second half, effort, estimates.

    t (N,) s; eta, eta_d, tau, tau_hat (N, 6); true_disturbance (6,) or None."""
    pos, att = tracking_errors(eta, eta_d)
    steady = t >= t[0] + 0.5 * (t[-1] - t[0]) if t.size else np.zeros(0, bool)
    dt = np.diff(t)
    effort = float(np.sum(np.sum(tau[:-1] ** 2, axis=1) * dt)) if t.size > 1 else 0.0
    return {
        "mission": mission,
        "controller": controller,
        "duration_s": float(t[-1] - t[0]) if t.size else 0.0,
        "rms_position_error_m": _rms(pos),
        "max_position_error_m": float(pos.max()) if pos.size else float("nan"),
        "rms_attitude_error_rad": _rms(att),
        "rms_position_error_steady_m": _rms(pos[steady]),
        "rms_attitude_error_steady_rad": _rms(att[steady]),
        "control_effort": effort,
        "final_disturbance_estimate": [float(v) for v in tau_hat[-1]] if len(tau_hat) else None,
        "true_disturbance": None if true_disturbance is None else [float(v) for v in true_disturbance],
        "completed": bool(completed),
    }


def trace_metrics(mission: str, controller: str, trace) -> dict:
    """`run_metrics` of an offline run (a `rov_mav.offline.simulation.Trace`)."""
    return run_metrics(mission, controller, trace.t, trace.eta, trace.reference[:, :6], trace.tau, trace.tau_hat,
                       trace.true_disturbance, trace.completed)


def pwm_activity(t: np.ndarray, pwm: np.ndarray) -> float:
    """Mean over the thrusters of sum |delta PWM| per second (us/s): how much a run moves its thrusters, noise turned
    into thruster activity included. t (N,) s; pwm (N, n) us, NaN rows (no output known) skipped."""
    known = np.all(np.isfinite(pwm), axis=1)
    t, pwm = t[known], pwm[known]
    span = float(t[-1] - t[0]) if t.size > 1 else 0.0
    return float(np.mean(np.sum(np.abs(np.diff(pwm, axis=0)), axis=0)) / span) if span > 0 else float("nan")


def loop_figures(tick_t: np.ndarray, latency_ms: np.ndarray) -> dict:
    """A run's `loop` block: ticks, achieved rate (ticks per vehicle s), telemetry-in to command-out latency p50 / p99
    (ms, over the finite values: a tick between samples has none)."""
    span = float(tick_t[-1] - tick_t[0]) if tick_t.size > 1 else 0.0
    return {
        "ticks": int(tick_t.size),
        "control_rate_hz": (tick_t.size - 1) / span if span > 0 else 0.0,
        "latency_p50_ms": finite_percentile(latency_ms, 50),
        "latency_p99_ms": finite_percentile(latency_ms, 99),
    }


def finite_percentile(values: np.ndarray, q: float) -> float:
    """The q-th percentile of the finite values (NaN if none)."""
    values = values[np.isfinite(values)]
    return float(np.percentile(values, q)) if values.size else float("nan")

