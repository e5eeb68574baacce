"""Figures of a run (PNG): the six DOF against the reference, the 3D path, the estimates, the adaptation rates."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from rov_mav.offline.simulation import Trace  # noqa: E402

DOF_LABELS = ("x (m)", "y (m)", "z (m)", "phi (rad)", "theta (rad)", "psi (rad)")
ETA_NAMES = ("x", "y", "z", "phi", "theta", "psi")
BODY_LABELS = ("u: X (N)", "v: Y (N)", "w: Z (N)", "p: K (N m)", "q: M (N m)", "r: N (N m)")
BUCKETS = 2000                # a line of more samples is drawn as the lowest and highest of this many time buckets


def _envelope(t: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(t, y) thinned for drawing: per bucket of consecutive samples its lowest and highest, in time order, so that
    every spike a figure could show stays (an hour's log is hundreds of thousands of samples; a figure is 1200
    pixels wide)."""
    n = len(t)
    if n <= 2 * BUCKETS:
        return t, y
    size = n // BUCKETS
    whole = (n // size) * size
    buckets = np.asarray(y[:whole], dtype=float).reshape(-1, size)
    low = np.argmin(np.where(np.isnan(buckets), np.inf, buckets), axis=1)
    high = np.argmax(np.where(np.isnan(buckets), -np.inf, buckets), axis=1)
    start = np.arange(buckets.shape[0]) * size
    index = np.concatenate([np.sort(np.column_stack([start + low, start + high]), axis=1).ravel(),
                            np.arange(whole, n)])
    return t[index], y[index]


def _line(ax, t: np.ndarray, y: np.ndarray, *args, **kwargs):
    return ax.plot(*_envelope(np.asarray(t), np.asarray(y)), *args, **kwargs)


def _grid(title: str):
    fig, axes = plt.subplots(3, 2, figsize=(11, 8), sharex=True)
    fig.suptitle(title)
    return fig, axes.T.ravel()


def _save(fig, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _on_reference_branch(angle: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """A heading drawn on its reference's branch (the reference plus the wrapped error): a vehicle at -179 deg
    against a reference of 181 deg is 2 deg off, not a line across the figure."""
    return reference + (angle - reference + np.pi) % (2.0 * np.pi) - np.pi


def plot_dofs(trace: Trace, title: str, path: Path) -> Path:
    """Each DOF against its reference (the counterpart of Figs. IV-2, IV-3)."""
    fig, axes = _grid(title)
    for i, ax in enumerate(axes):
        _line(ax, trace.t, trace.reference[:, i], "k--", lw=1, label="reference")
        _line(ax, trace.t, _on_reference_branch(trace.eta[:, i], trace.reference[:, i]) if i == 5 else
              trace.eta[:, i], lw=1.2, label="vehicle")
        ax.set_ylabel(DOF_LABELS[i])
        ax.grid(alpha=0.3)
    axes[0].legend(loc="best")
    for ax in (axes[2], axes[5]):
        ax.set_xlabel("t (s)")
    return _save(fig, path)


def plot_path(traces: dict[str, Trace], title: str, path: Path, planned: np.ndarray | None = None) -> Path:
    """3D path of one or more runs against the reference (Figs. IV-4, IV-7), or against `planned` (M, 3) waypoints
    when given; NED drawn with depth down."""
    fig = plt.figure(figsize=(8, 6.5))
    ax = fig.add_subplot(projection="3d")
    first = next(iter(traces.values()))
    if planned is not None:
        ax.plot(planned[:, 1], planned[:, 0], planned[:, 2], "k--o", lw=1, ms=4, label="waypoints")
    else:
        every = max(1, len(first.t) // (2 * BUCKETS))
        reference = first.reference[::every]
        ax.plot(reference[:, 1], reference[:, 0], reference[:, 2], "k--", lw=1, label="reference")
    for name, trace in traces.items():
        every = max(1, len(trace.t) // (2 * BUCKETS))
        ax.plot(trace.eta[::every, 1], trace.eta[::every, 0], trace.eta[::every, 2], lw=1.3, label=name)
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.set_zlabel("depth (m)")
    ax.invert_zaxis()
    ax.set_title(title)
    ax.legend(loc="best")
    return _save(fig, path)


def plot_estimates(trace: Trace, title: str, path: Path) -> Path:
    """Disturbance estimates against the true disturbance (Figs. IV-5, IV-6, IV-8)."""
    fig, axes = _grid(title)
    for i, ax in enumerate(axes):
        _line(ax, trace.t, trace.tau_hat[:, i], lw=1.2, label="estimate")
        if trace.true_disturbance is not None:
            ax.axhline(trace.true_disturbance[i], color="k", ls="--", lw=1, label="true")
        ax.set_ylabel(BODY_LABELS[i])
        ax.grid(alpha=0.3)
    axes[0].legend(loc="best")
    return _save(fig, path)


def plot_rates(trace: Trace, title: str, path: Path) -> Path:
    """Adaptation rates gamma per body DOF (fuzzy or constant)."""
    fig, axes = _grid(title)
    for i, ax in enumerate(axes):
        _line(ax, trace.t, trace.gamma[:, i], lw=1)
        ax.set_ylabel(f"gamma {'uvwpqr'[i]}")
        ax.grid(alpha=0.3)
    return _save(fig, path)


def plot_run(trace: Trace, label: str, out_dir: Path) -> list[Path]:
    """The four standard figures of one run, written to out_dir; returns their paths."""
    out_dir.mkdir(parents=True, exist_ok=True)
    return [
        plot_dofs(trace, f"{label}: tracking per DOF", out_dir / "dofs.png"),
        plot_path({label: trace}, f"{label}: 3D path", out_dir / "path3d.png"),
        plot_estimates(trace, f"{label}: disturbance estimate", out_dir / "estimates.png"),
        plot_rates(trace, f"{label}: adaptation rates", out_dir / "rates.png"),
    ]


def plot_thrusters(series: dict[str, tuple[np.ndarray, np.ndarray]], limits: tuple[np.ndarray, np.ndarray],
                   title: str, path: Path) -> Path:
    """Each thruster's PWM over time, one line per source (e.g. commanded, the vehicle's outputs), with its
    limits: series name -> (t (M,), pwm (M, 8)); limits (low (8,), high (8,)) us."""
    fig, axes = plt.subplots(4, 2, figsize=(11, 9), sharex=True, sharey=True)
    fig.suptitle(title)
    for i, ax in enumerate(axes.T.ravel()):
        for name, (t, pwm) in series.items():
            _line(ax, t, pwm[:, i], lw=1, label=name)
        for limit in (limits[0][i], limits[1][i]):
            ax.axhline(limit, color="r", ls=":", lw=1)
        ax.set_ylabel(f"T{i + 1} PWM (us)")
        ax.grid(alpha=0.3)
    axes[0, 0].legend(loc="best", fontsize=8)
    for ax in axes[-1]:
        ax.set_xlabel("t (s)")
    return _save(fig, path)


def plot_timeline(panels: list[tuple[str, dict[str, tuple[np.ndarray, np.ndarray]]]], title: str,
                  path: Path, marks: list[tuple[float, str]] = ()) -> Path:
    """Stacked time series sharing t: panels of (y label, {name: (t, values)}), and vertical marks (t, label)."""
    fig, axes = plt.subplots(len(panels), 1, figsize=(11, 2.6 * len(panels)), sharex=True, squeeze=False)
    fig.suptitle(title)
    for ax, (label, lines) in zip(axes[:, 0], panels):
        for name, (t, values) in lines.items():
            _line(ax, t, values, ".-" if len(t) < 200 else "-", lw=1, ms=3, label=name)
        if marks:                           # one collection for every mark: an hour's dive has many
            ax.vlines([t_mark for t_mark, _ in marks], 0.0, 1.0, transform=ax.get_xaxis_transform(), color="0.6",
                      ls="--", lw=0.8)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        if len(lines) > 1:
            ax.legend(loc="best", fontsize=8)
    for t_mark, text in marks:
        axes[0, 0].annotate(text, (t_mark, 1.0), xycoords=("data", "axes fraction"), rotation=90, fontsize=7,
                            va="top", ha="right")
    axes[-1, 0].set_xlabel("t (s)")
    return _save(fig, path)


def plot_fit(fits, title: str, path: Path) -> Path:
    """identify's fit per DOF (`identification.DofFit`): the R^2 of each force balance it could compute."""
    dofs = [f for f in fits if np.isfinite(f.r2)]
    fig, ax = plt.subplots(figsize=(6, 3))
    ax.bar([f.dof for f in dofs], [f.r2 for f in dofs], color="#1f77b4")
    ax.set_ylim(min(0.0, *(f.r2 for f in dofs)), 1.0)
    ax.set_ylabel("R^2 of the force balance")
    ax.set_title(title)
    return _save(fig, path)


def plot_convergence(cost_history: np.ndarray, gain_history: np.ndarray, title: str, path: Path) -> Path:
    """PSO convergence (the counterpart of Fig. IV-1): (i) best cost per iteration, (ii) the 12 gains per iteration."""
    it = np.arange(1, len(cost_history) + 1)
    fig, (ax_cost, ax_gain) = plt.subplots(1, 2, figsize=(12, 4.5))
    fig.suptitle(title)
    ax_cost.plot(it, cost_history, lw=1.4)
    if cost_history.max() > 10 * cost_history.min() > 0:     # log scale only when it spans decades
        ax_cost.set_yscale("log")
    ax_cost.set_xlabel("iteration")
    ax_cost.set_ylabel("best cost J (Eq. 2.32)")
    ax_cost.set_title("(i) best cost")
    ax_cost.grid(alpha=0.3, which="both")
    colors = plt.get_cmap("tab10").colors
    for i in range(6):
        ax_gain.plot(it, gain_history[:, i], color=colors[i], lw=1.2, label=f"k1 {ETA_NAMES[i]}")
        ax_gain.plot(it, gain_history[:, 6 + i], color=colors[i], lw=1.2, ls="--", label=f"k2 {ETA_NAMES[i]}")
    ax_gain.set_xlabel("iteration")
    ax_gain.set_ylabel("gain (1/s)")
    ax_gain.set_title("(ii) best gains: k1 solid, k2 dashed")
    ax_gain.legend(ncol=6, fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.14))
    ax_gain.grid(alpha=0.3)
    return _save(fig, path)


def plot_bench(values: dict[str, dict[str, np.ndarray]], title: str, path: Path) -> Path:
    """Box plots of held-out figures per controller: values[panel title][controller] = one value per completed run
    (already in the panel's unit). Boxes: quartiles; whiskers: 1.5 IQR; points: runs beyond."""
    panels = list(values.items())
    fig, axes = plt.subplots(1, len(panels), figsize=(4.2 * len(panels), 4.5), squeeze=False)
    fig.suptitle(title)
    for ax, (label, per_controller) in zip(axes[0], panels):
        names = list(per_controller)
        ax.boxplot([per_controller[n] for n in names], tick_labels=names)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3, axis="y")
        ax.tick_params(axis="x", rotation=30)
    return _save(fig, path)
