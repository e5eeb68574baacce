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
    from rov_mav.offline.plots import plot_fit, plot_timeline     # matplotlib loads only when the report is drawn

    plot_fit(fits, "The fit per degree of freedom", out / "fit.png")
    plot_timeline([("position error (cm)", {f"{label} gains": (t, 100.0 * error)
                                            for label, (t, error) in errors.items()})],
                  "The check square, old gains against new", out / "check.png")
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
