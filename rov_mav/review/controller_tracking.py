"""Controllers measured against their own targets, ArduSub's and rov-mav's alike, so that a pilot's dive in ALT_HOLD
or SURFTRAK and a rov-mav run compare on one page: for each armed stretch of one ArduSub mode, how far the vehicle
was from the targets ArduSub itself logged (RMS and largest); for a rov-mav run, the same figures of its flown
mission against the reference it flew (ticks.csv).

The targets, by source:
- a DataFlash log: depth from CTUN's DAlt (the position controller's altitude target) against Alt (its altitude
  estimate), `Sub::Log_Write_Control_Tuning` (ArduSub/Log.cpp); height above the bottom from CTUN's DSAlt (SURFTRAK's
  rangefinder target) against SAlt (the rangefinder's altitude), where both are set; the horizontal position from
  PSCN/PSCE's TPN/TPE against PN/PE, the velocities from their TVN/TVE against VN/VE and PSCD's TVD against VD
  (`AC_PosControl::Write_PSCN`, `Write_PSCE`, `Write_PSCD`: m and m/s since 4.1); attitude from ATT's DesRoll,
  DesPitch, DesYaw (the attitude controller's targets, `Sub::Log_Write_Attitude`) against Roll, Pitch, Yaw;
- a telemetry log: NAV_CONTROLLER_OUTPUT, whose alt_error is the position controller's altitude error and whose
  nav_roll, nav_pitch and nav_bearing are the attitude targets (`GCS_MAVLINK_Sub::send_nav_controller_output`,
  ArduSub/GCS_Mavlink.cpp), against ATTITUDE.
Each figure counts only in the modes whose controller holds that target (MANUAL holds none; STABILIZE attitude only).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rov_mav.flight.session.link import mode_name
from rov_mav.review.series import last_known

STABILIZE, ALT_HOLD, AUTO, GUIDED, CIRCLE, POSHOLD, SURFTRAK = 0, 2, 3, 4, 7, 16, 21
HOLDS = {                               # signal -> the modes (custom_mode) whose controller holds its target
    "depth_m": {ALT_HOLD, AUTO, GUIDED, CIRCLE, POSHOLD, SURFTRAK},
    "height_above_bottom_m": {SURFTRAK},
    "horizontal_m": {AUTO, GUIDED, CIRCLE, POSHOLD},
    "vertical_velocity_mps": {ALT_HOLD, AUTO, GUIDED, CIRCLE, POSHOLD, SURFTRAK},
    "horizontal_velocity_mps": {AUTO, GUIDED, CIRCLE, POSHOLD},
    "roll_deg": {STABILIZE, ALT_HOLD, AUTO, GUIDED, CIRCLE, POSHOLD, SURFTRAK},
    "pitch_deg": {STABILIZE, ALT_HOLD, AUTO, GUIDED, CIRCLE, POSHOLD, SURFTRAK},
    "yaw_deg": {STABILIZE, ALT_HOLD, AUTO, GUIDED, CIRCLE, POSHOLD, SURFTRAK},
}
MIN_SAMPLES = 5                         # fewer samples of a signal in a stretch make no figure


@dataclass(frozen=True)
class Errors:
    """One target's error (target minus actual, or its size) at log times `t` (s)."""

    t: np.ndarray
    error: np.ndarray


@dataclass(frozen=True)
class Stretch:
    """An armed stretch of one mode: [start, end) in log time."""

    mode: int
    start: float
    end: float


def armed_stretches(wall: np.ndarray, armed: np.ndarray, mode: np.ndarray, end: float) -> list[Stretch]:
    """The armed stretches of one mode each, from the vehicle's state changes (HEARTBEATs: time, armed, mode); the
    last runs to `end`."""
    out: list[Stretch] = []
    current: tuple[int, float] | None = None
    for t, is_armed, m in zip(wall, armed, mode):
        state = int(m) if is_armed else None
        if current is not None and state == current[0]:
            continue
        if current is not None and current[0] is not None:
            out.append(Stretch(current[0], current[1], float(t)))
        current = (state, float(t))
    if current is not None and current[0] is not None and end > current[1]:
        out.append(Stretch(current[0], current[1], end))
    return out


def figures(stretches: list[Stretch], errors: dict[str, Errors]) -> list[dict]:
    """Per stretch whose mode holds a target the log has: each such target's RMS and largest error, and samples."""
    out = []
    for stretch in stretches:
        holding = {name: series for name, series in errors.items() if stretch.mode in HOLDS[name]}
        entry = stretch_figures(mode_name(stretch.mode), stretch.start, stretch.end, holding)
        if entry["errors"]:
            out.append(entry)
    return out


def held(stretches: list[Stretch], errors: dict[str, Errors]) -> dict[str, Errors]:
    """Each target's errors only where a stretch's mode held it (what a figure of ArduSub's control should show)."""
    out = {}
    for name, series in errors.items():
        inside = np.zeros(series.t.size, dtype=bool)
        for stretch in stretches:
            if stretch.mode in HOLDS[name]:
                inside |= (series.t >= stretch.start) & (series.t < stretch.end)
        inside &= np.isfinite(series.error)
        if inside.any():
            out[name] = Errors(series.t[inside], series.error[inside])
    return out


def stretch_figures(label: str, start: float, end: float, errors: dict[str, Errors]) -> dict:
    """Each target's RMS and largest error over [start, end), and its samples (none with fewer than MIN_SAMPLES)."""
    signals = {}
    for name, series in errors.items():
        inside = (series.t >= start) & (series.t < end) & np.isfinite(series.error)
        if inside.sum() < MIN_SAMPLES:
            continue
        error = np.abs(series.error[inside])
        signals[name] = {"rms": float(np.sqrt(np.mean(error ** 2))), "max": float(error.max()),
                         "samples": int(inside.sum())}
    return {"mode": label, "from_s": start, "to_s": end, "errors": signals}


def run_errors(t: np.ndarray, eta: np.ndarray, eta_d: np.ndarray) -> dict[str, Errors]:
    """A rov-mav run's errors under the same names: depth and horizontal position (m), roll, pitch and heading (deg)
    of the states (N, 6) against the reference the law flew."""
    out = {"depth_m": Errors(t, eta_d[:, 2] - eta[:, 2]),
           "horizontal_m": Errors(t, np.hypot(eta_d[:, 0] - eta[:, 0], eta_d[:, 1] - eta[:, 1]))}
    for i, axis in enumerate(("roll", "pitch", "yaw")):
        out[f"{axis}_deg"] = Errors(t, angle_error_deg(np.degrees(eta_d[:, 3 + i]), np.degrees(eta[:, 3 + i])))
    return out


def angle_error_deg(target_deg: np.ndarray, actual_deg: np.ndarray) -> np.ndarray:
    """target - actual, wrapped into [-180, 180) degrees."""
    return (np.asarray(target_deg) - np.asarray(actual_deg) + 180.0) % 360.0 - 180.0


def dataflash_errors(records: dict) -> dict[str, Errors]:
    """The targets a DataFlash log holds (see the module): `records` as `dataflash_records.read_records` gives
    CTUN, PSCN, PSCE, PSCD and ATT."""
    out: dict[str, Errors] = {}
    ctun = records.get("CTUN")
    if ctun is not None and "DAlt" in ctun and "Alt" in ctun:
        t = ctun["TimeUS"] * 1e-6
        out["depth_m"] = Errors(t, ctun["DAlt"] - ctun["Alt"])
        if "DSAlt" in ctun and "SAlt" in ctun:
            held = (ctun["DSAlt"] > 0) & (ctun["SAlt"] > 0)     # SURFTRAK has a target, the rangefinder a reading
            out["height_above_bottom_m"] = Errors(t[held], (ctun["DSAlt"] - ctun["SAlt"])[held])
    north, east = records.get("PSCN"), records.get("PSCE")
    if north is not None and east is not None and len(north) and len(east):
        t = north["TimeUS"] * 1e-6
        east_error = np.interp(t, east["TimeUS"] * 1e-6, east["TPE"] - east["PE"])
        out["horizontal_m"] = Errors(t, np.hypot(north["TPN"] - north["PN"], east_error))
        if "TVN" in north and "TVE" in east:
            east_speed = np.interp(t, east["TimeUS"] * 1e-6, east["TVE"] - east["VE"])
            out["horizontal_velocity_mps"] = Errors(t, np.hypot(north["TVN"] - north["VN"], east_speed))
    down = records.get("PSCD")
    if down is not None and len(down) and "TVD" in down:
        out["vertical_velocity_mps"] = Errors(down["TimeUS"] * 1e-6, down["TVD"] - down["VD"])
    att = records.get("ATT")
    if att is not None and "DesRoll" in att:
        t = att["TimeUS"] * 1e-6
        for axis, target, actual in (("roll", "DesRoll", "Roll"), ("pitch", "DesPitch", "Pitch"),
                                     ("yaw", "DesYaw", "Yaw")):
            out[f"{axis}_deg"] = Errors(t, angle_error_deg(att[target], att[actual]))
    return out


def telemetry_errors(nav_wall: np.ndarray, nav: np.ndarray, attitude_wall: np.ndarray,
                     attitude: np.ndarray) -> dict[str, Errors]:
    """The targets a telemetry log holds: NAV_CONTROLLER_OUTPUT (`nav`: nav_roll, nav_pitch, nav_bearing in
    degrees, alt_error in m) against ATTITUDE (rad) at the nearest earlier sample."""
    if not nav_wall.size:
        return {}
    out = {"depth_m": Errors(nav_wall, nav[:, 3])}
    if attitude_wall.size:
        actual = np.degrees(last_known(attitude_wall, attitude, nav_wall))
        for i, axis in enumerate(("roll", "pitch", "yaw")):
            out[f"{axis}_deg"] = Errors(nav_wall, angle_error_deg(nav[:, i], actual[:, i]))
    return out


def describe(entry: dict) -> str:
    """One line of a stretch's figures."""
    units = {"m": ("cm", 100.0), "mps": ("cm/s", 100.0), "deg": ("deg", 1.0)}
    parts = []
    for name, figure in entry["errors"].items():
        label, unit = name.rsplit("_", 1)
        shown, scale = units[unit]
        parts.append(f"{label.replace('_', ' ')} {figure['rms'] * scale:.1f} {shown} RMS "
                     f"(max {figure['max'] * scale:.1f})")
    span = entry["to_s"] - entry["from_s"]
    return f"{entry['mode']} {entry['from_s']:.1f}-{entry['to_s']:.1f} s ({span:.0f} s): " + ", ".join(parts)
