"""autotune's one-page report: report.md in its --out folder, with the fit per DOF, the tune's convergence (drawn
by `rov-mav tune`) and the check square flown with the old gains and the new, old against new in figures and a
table."""

from __future__ import annotations

from pathlib import Path

import numpy as np

CHECK_ROWS = (("position RMS (cm)", "rms_position_error_m", 100.0), ("position max (cm)", "max_position_error_m", 100.0),
              ("position RMS against the truth (cm)", "rms_position_error_truth_m", 100.0),
              ("attitude RMS (deg)", "rms_attitude_error_rad", float(np.degrees(1.0))))


def write_report(out: Path, runs: dict, key: str, fits, verdict: str,
                 errors: dict[str, tuple[np.ndarray, np.ndarray]]) -> Path:
    """report.md (and fit.png, check.png beside it) from the check runs' metrics (`runs["old"]`, `runs["new"]`), the
    error they were judged on (`key`), identify's fit per DOF, the verdict, and each check's (t, position error)."""
    _draw_fit(fits, out / "fit.png")
    _draw_check(errors, out / "check.png")
    rows = [f"| {label} | {runs['old'][k] * scale:.2f} | {runs['new'][k] * scale:.2f} |"
            for label, k, scale in CHECK_ROWS if k in runs["old"] and k in runs["new"]]
    rows.append(f"| thruster activity (us/s) | {runs['old']['loop']['pwm_activity_us_per_s']:.0f} | "
                f"{runs['new']['loop']['pwm_activity_us_per_s']:.0f} |")
    dofs = "\n".join(f"| {f.dof} | {f.r2:.3f} | {f.rms:.3g} {f.unit} |" for f in fits if np.isfinite(f.r2))
    text = f"""# Autotune

{verdict[0].upper() + verdict[1:]} (judged on {key}).

## The check square, old gains against new

![Position error on the check square](check.png)

| | old | new |
|---|---:|---:|
{chr(10).join(rows)}

## The fit (vehicle.yaml)

![How much of each degree of freedom's force the fitted model explains](fit.png)

| DOF | R^2 | residual RMS |
|---|---:|---:|
{dofs}

## The tune (tuned-gains.yaml)

![The swarm's best cost per iteration](tune/convergence.png)
"""
    (out / "report.md").write_text(text)
    return out / "report.md"


def _pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _draw_fit(fits, path: Path) -> None:
    plt = _pyplot()
    dofs = [f for f in fits if np.isfinite(f.r2)]
    fig, ax = plt.subplots(figsize=(6, 3))
    ax.bar([f.dof for f in dofs], [f.r2 for f in dofs], color="#1f77b4")
    ax.set_ylim(min(0.0, *(f.r2 for f in dofs)), 1.0)
    ax.set_ylabel("R^2 of the force balance")
    ax.set_title("The fit per degree of freedom")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def _draw_check(errors: dict[str, tuple[np.ndarray, np.ndarray]], path: Path) -> None:
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(8, 3))
    for label, colour in (("old", "#7f7f7f"), ("new", "#1f77b4")):
        t, error = errors[label]
        ax.plot(t, 100.0 * error, color=colour, label=f"{label} gains")
    ax.set_xlabel("mission time (s)")
    ax.set_ylabel("position error (cm)")
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
