"""What a DataFlash log holds beyond the telemetry, summed up for the review: the EKF's own health and the motors'
limits, each at the log's own rate.

- EKF3 (core 0): XKF4's innovation test ratios SV, SP, SH, SM (velocity, position, height, compass: a measurement
  whose ratio passes 1 is rejected by the filter; `NavEKF3_core::Log_Write_XKF4`) and XKF3's innovations (IVN, IVE,
  IVD m/s; IPN, IPE, IPD m): the largest ratio, the share of samples rejected, the innovations' RMS;
- the motors (MOTB, `AP_MotorsMulticopter::Log_Write`): LiftMax (the lift the battery's voltage leaves, 1 = full),
  ThLimit (the throttle limit): their lowest, and the share of samples the throttle was limited;
- external navigation (VISP/VISV: a DVL or other odometry through AP_VisualOdom): how many samples, their quality.
"""

from __future__ import annotations

import numpy as np

from rov_mav.review.dataflash_records import Records, first_core

RATIOS = {"velocity": "SV", "position": "SP", "height": "SH", "compass": "SM"}
INNOVATIONS = {"velocity_m_s": ("IVN", "IVE", "IVD"), "position_m": ("IPN", "IPE", "IPD")}
TYPES = ("XKF3", "XKF4", "MOTB", "VISP", "VISV")


def onboard(records: dict[str, Records]) -> dict:
    """The summary of each part the log holds (a part it lacks is left out)."""
    out = {}
    if (ekf := _ekf(records.get("XKF3"), records.get("XKF4"))) is not None:
        out["ekf"] = ekf
    if (motors := _motors(records.get("MOTB"))) is not None:
        out["motors"] = motors
    odometry = {name: len(records[name]) for name in ("VISP", "VISV") if records.get(name) is not None}
    if odometry:
        quality = [records[name]["Qual"] for name in ("VISP", "VISV") if name in records and "Qual" in records[name]]
        out["external_navigation"] = {"samples": odometry, "quality_min": float(min(q.min() for q in quality))
                                      if quality else None}
    return out


def _ekf(xkf3: Records | None, xkf4: Records | None) -> dict | None:
    xkf3, xkf4 = first_core(xkf3), first_core(xkf4)
    if xkf3 is None and xkf4 is None:
        return None
    out: dict = {"samples": len(xkf4) if xkf4 is not None else len(xkf3)}
    if xkf4 is not None:
        ratios = {name: xkf4[label] for name, label in RATIOS.items() if label in xkf4}
        out["test_ratio_max"] = {name: float(np.nanmax(v)) for name, v in ratios.items()}
        out["rejected_share"] = {name: float(np.mean(v > 1.0)) for name, v in ratios.items()}
    if xkf3 is not None:
        out["innovation_rms"] = {name: [float(np.sqrt(np.nanmean(xkf3[label] ** 2))) for label in labels]
                                 for name, labels in INNOVATIONS.items() if all(label in xkf3 for label in labels)}
    return out


def _motors(motb: Records | None) -> dict | None:
    if motb is None or not len(motb):
        return None
    out: dict = {"samples": len(motb)}
    if "LiftMax" in motb:
        out["lift_max_min"] = float(np.nanmin(motb["LiftMax"]))
    if "ThLimit" in motb:
        out["throttle_limit_min"] = float(np.nanmin(motb["ThLimit"]))
        out["throttle_limited_share"] = float(np.mean(motb["ThLimit"] < 1.0))
    return out


def describe(summary: dict) -> list[str]:
    """The summary's lines."""
    lines = []
    if ekf := summary.get("ekf"):
        if "test_ratio_max" in ekf:
            ratios = ", ".join(f"{name} {value:.2f} ({ekf['rejected_share'][name]:.1%} rejected)"
                               for name, value in ekf["test_ratio_max"].items())
            lines.append(f"  EKF (XKF4, core 0): largest innovation test ratio {ratios}")
        if rms := ekf.get("innovation_rms"):
            parts = [f"{name.split('_')[0]} NED {', '.join(f'{v:.3g}' for v in values)} {name.split('_', 1)[1]}"
                     for name, values in rms.items()]
            lines.append("  EKF (XKF3): innovation RMS " + "; ".join(parts).replace("m_s", "m/s"))
    if motors := summary.get("motors"):
        parts = []
        if "lift_max_min" in motors:
            parts.append(f"lift left by the battery at least {motors['lift_max_min']:.2f}")
        if "throttle_limit_min" in motors:
            parts.append(f"throttle limit down to {motors['throttle_limit_min']:.2f} "
                         f"({motors['throttle_limited_share']:.1%} of samples limited)")
        lines.append("  motors (MOTB): " + ", ".join(parts))
    if nav := summary.get("external_navigation"):
        counts = ", ".join(f"{name} {n}" for name, n in nav["samples"].items())
        lines.append(f"  external navigation (AP_VisualOdom): {counts} samples")
    return lines
