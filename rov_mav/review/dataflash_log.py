"""A vehicle's own DataFlash log (.BIN: ArduSub's on-board log, or the built-in vehicle's) read as a `Dive`, column by
column from its records (`dataflash_records`), so that `analyze` reviews it as it reviews a .tlog.

Fields by label through the file's own FMT records (layouts differ from ArduSub 4.0 to 4.7: ATT in centidegrees or
float degrees, EKF2's NKF1 or EKF3's XKF1 with or without a core field, BAT with or without RemPct). Times are
TimeUS, both the log time and the vehicle's (a DataFlash log has no wall clock without GPS). What each part is:
- the state: each XKF1 (core 0; NKF1 in EKF2 logs) paired with the ATT nearest it within half ATT's period, the
  older of the two brought forward to the newer one's time by its own rates (the NED velocity; RATE's body rates
  through T(Theta)), as `vehicle_state.StateDecoder` pairs ATTITUDE and LOCAL_POSITION_NED live; nu = [R^T v_NED,
  p, q, r];
- outputs RCOU; battery BAT (or CURR) instance 0, a value out of its field's range unknown (BAT.RemPct 255 is
  ArduPilot's "unknown"; a negative current, a sensor's offset, unknown as SYS_STATUS has it); the Bar30 BARO
  instance 1; ArduSub's own altitude CTUN.Alt; a down-looking rangefinder's good readings (RFND.Stat 4);
- arming and modes: MODE, ARM (EV 10/11 in older logs) in file order, from the state the log began in (ArduSub opens a
  log at arming unless LOG_DISARMED is 1, `AP_Logger::should_log`, and the arming that opened it is not in it);
- texts MSG ("GCS:" or "SRC=sysid/compid:" before a station's text, `GCS_MAVLINK::handle_statustext`), PARM;
- ArduSub's own targets for `controller_tracking` (CTUN, PSCN/PSCE, ATT); the EKF's health, the motors' limits and
  external navigation (`onboard`).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from rov_mav.flight.session.link import CHANNELS, mavlink
from rov_mav.model.dynamics import euler_rate_matrix, rotation
from rov_mav.review import controller_tracking, onboard
from rov_mav.review.dataflash_records import Records, first_core, index_dataflash
from rov_mav.review.dive import Dive
from rov_mav.review.tlog import ReadReport
from rov_mav.units import wrap_angle

VEHICLE = (1, 1)
GCS_SYSID = 255
_SOURCE = re.compile(r"^SRC=(\d+)/(\d+):")
EV_ARMED, EV_DISARMED = 10, 11          # LogEvent ids (AP_Logger/LogStructure.h)
BAR30_INSTANCE = 1                      # ArduSub's second barometer: the Bar30 (SCALED_PRESSURE2 on the link)
DOWN = 25                               # MAV_SENSOR_ROTATION_PITCH_270: a rangefinder looking down
RANGEFINDER_GOOD = 4                    # RFND.Stat (`RangeFinder::Status`): 0 not connected, 1 no data, 2 out of range
                                        # low, 3 high, 4 good: only a good reading is a distance
TYPES = ("ATT", "RATE", "XKF1", "NKF1", "RCOU", "BAT", "CURR", "BARO", "CTUN", "RFND", "MODE", "ARM", "EV", "MSG",
         "PARM", "PSCN", "PSCE", "PSCD")
_RC_LABELS = [[f"C{i}", f"Ch{i}", f"Chan{i}"] for i in range(1, 17)]


def read_dataflash_dive(path: str | Path, report: ReadReport) -> Dive:
    """The Dive a .BIN holds; `report` says what was read (records, damaged stretches, where it stopped)."""
    index = index_dataflash(path, report)
    r = dict(index.records(TYPES + onboard.TYPES))
    timed = [records for records in r.values() if len(records) and "TimeUS" in records]
    if timed:
        last = max(timed, key=lambda records: records.offsets[-1])        # the latest record in the file
        report.last_wall = float(last["TimeUS"][-1]) * 1e-6
    state_t, state_wall, eta, nu = _states(r)
    attitude = r.get("ATT")
    att_t = attitude["TimeUS"] * 1e-6 if attitude is not None else np.zeros(0)
    params, param_changes = _parameters(r.get("PARM"))
    texts, others = _texts(r.get("MSG"))
    heartbeat_wall, armed, mode = _arming_and_modes(r, params)
    servo_t, servo = _outputs(r.get("RCOU"))
    power_wall, voltage, current, consumed = _battery(r)
    pressure_wall, pressure = _bar30(r.get("BARO"))
    altitude_wall, altitude = _altitude(r.get("CTUN"))
    range_wall, range_m = _rangefinder(r.get("RFND"))
    return Dive(
        vehicle=VEHICLE if (state_t.size or att_t.size or heartbeat_wall.size) else None,
        vehicle_type=mavlink.MAV_TYPE_SUBMARINE,
        state_t=state_t, state_wall=state_wall, eta=eta, nu=nu,
        clock_wall=att_t, clock_t=np.floor(att_t * 1e3) / 1e3,
        servo_t=servo_t, servo=servo, overrides={}, joysticks={}, motor_tests={},
        power_wall=power_wall, voltage=voltage, current=current, consumed_wall=power_wall, consumed_mah=consumed,
        heartbeat_wall=heartbeat_wall, armed=armed, mode=mode,
        texts=texts, params=params, param_changes=param_changes,
        mission={}, mission_complete=False, mission_progress=[], home=None, origin=None, others=others,
        attitude_wall=att_t, attitude=_attitude(attitude),
        pressure_wall=pressure_wall, pressure_abs=pressure, altitude_wall=altitude_wall, altitude=altitude,
        range_wall=range_wall, range_m=range_m,
        targets=controller_tracking.dataflash_errors(r), onboard=onboard.onboard(r))


def _states(r: dict[str, Records]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(t, wall, eta (N, 6), nu (N, 6)): each position sample paired with the nearest attitude (see the module)."""
    empty = (np.zeros(0), np.zeros(0), np.zeros((0, 6)), np.zeros((0, 6)))
    position, attitude = first_core(r.get("XKF1")), r.get("ATT")
    if position is None or not len(position):
        position = r.get("NKF1")
    if position is None or attitude is None or len(position) < 1 or len(attitude) < 2:
        return empty
    tp, ta = position["TimeUS"] * 1e-6, attitude["TimeUS"] * 1e-6
    half = 0.5 * float(np.median(np.diff(ta))) if ta.size > 1 else 0.0
    nearest = np.clip(np.searchsorted(ta, tp), 1, ta.size - 1)
    nearest = np.where(np.abs(ta[nearest - 1] - tp) <= np.abs(ta[nearest] - tp), nearest - 1, nearest)
    paired = np.abs(ta[nearest] - tp) <= half + 1e-6
    if not paired.any():
        return empty
    j = nearest[paired]
    tp, ta_j = tp[paired], ta[j]
    t = np.maximum(tp, ta_j)
    pos = np.column_stack([position[k][paired] for k in ("PN", "PE", "PD")])
    vel = np.column_stack([position[k][paired] for k in ("VN", "VE", "VD")])
    angles = np.radians(np.column_stack([attitude[k][j] for k in ("Roll", "Pitch", "Yaw")]))
    rates = _rates_at(r.get("RATE"), ta_j)
    pos = pos + vel * (t - tp)[:, None]
    eta_att = np.concatenate([np.zeros((t.size, 3)), angles], axis=1)
    angles = angles + np.einsum("kij,kj->ki", euler_rate_matrix(eta_att), rates) * (t - ta_j)[:, None]
    angles[:, 2] = wrap_angle(angles[:, 2])
    eta = np.concatenate([pos, angles], axis=1)
    body = np.einsum("kji,kj->ki", rotation(eta), vel)             # R^T v_NED
    return np.floor(t * 1e3) / 1e3, t, eta, np.concatenate([body, rates], axis=1)


def _rates_at(rate: Records | None, t: np.ndarray) -> np.ndarray:
    """The body rates (rad/s) of the last RATE record at or before each time (zero before the first)."""
    if rate is None or not len(rate):
        return np.zeros((t.size, 3))
    values = np.radians(np.column_stack([rate.get(k, 0.0) for k in ("R", "P", "Y")]))
    index = np.searchsorted(rate["TimeUS"] * 1e-6, t, side="right") - 1
    return np.where((index >= 0)[:, None], values[np.maximum(index, 0)], 0.0)


def _attitude(attitude: Records | None) -> np.ndarray:
    if attitude is None:
        return np.zeros((0, 3))
    angles = np.radians(np.column_stack([attitude[k] for k in ("Roll", "Pitch", "Yaw")]))
    angles[:, 2] = wrap_angle(angles[:, 2])
    return angles


def _outputs(rcou: Records | None) -> tuple[np.ndarray, np.ndarray]:
    if rcou is None:
        return np.zeros(0), np.zeros((0, CHANNELS))
    columns = []
    for labels in _RC_LABELS[:CHANNELS]:
        label = next((name for name in labels if name in rcou), None)
        columns.append(rcou[label].astype(float) if label is not None else np.zeros(len(rcou)))
    return rcou["TimeUS"] * 1e-6, np.column_stack(columns)


def _battery(r: dict[str, Records]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(t, V, A, mAh used) of battery instance 0; a value beyond what the vehicle's telemetry can carry, or a
    negative current, unknown (NaN), as SYS_STATUS and BATTERY_STATUS would say it."""
    battery = r.get("BAT") if r.get("BAT") is not None else r.get("CURR")
    if battery is None:
        return np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0)
    battery = battery.where((battery["Inst"] if "Inst" in battery else battery.get("Instance", 0.0)) == 0)
    volt, curr, used = battery.get("Volt"), battery.get("Curr"), battery.get("CurrTot")
    voltage = np.where((volt > 0) & (volt * 1000 < 65535), volt, np.nan)
    current = np.where((curr >= 0) & (curr * 100 <= 32767), curr, np.nan)
    consumed = np.where((used >= 0) & (used < 2 ** 31), used, np.nan)
    return battery["TimeUS"] * 1e-6, voltage, current, consumed


def _bar30(baro: Records | None) -> tuple[np.ndarray, np.ndarray]:
    if baro is None or "Press" not in baro:
        return np.zeros(0), np.zeros(0)
    bar30 = baro.where(baro.get("I", 0.0) == BAR30_INSTANCE)
    return bar30["TimeUS"] * 1e-6, bar30["Press"] / 100.0


def _altitude(ctun: Records | None) -> tuple[np.ndarray, np.ndarray]:
    """CTUN.Alt: Sub's altitude estimate (m, negative underwater)."""
    if ctun is None or "Alt" not in ctun:
        return np.zeros(0), np.zeros(0)
    known = np.isfinite(ctun["Alt"])
    return ctun["TimeUS"][known] * 1e-6, ctun["Alt"][known]


def _rangefinder(rfnd: Records | None) -> tuple[np.ndarray, np.ndarray]:
    if rfnd is None or "Dist" not in rfnd:
        return np.zeros(0), np.zeros(0)
    good = (rfnd.get("Orient", DOWN) == DOWN) & (rfnd.get("Stat", RANGEFINDER_GOOD) == RANGEFINDER_GOOD)
    return rfnd["TimeUS"][good] * 1e-6, rfnd["Dist"][good]


def _parameters(parm: Records | None) -> tuple[dict[str, float], list[tuple[float, str, float]]]:
    """The last value of each parameter, and (t, name, value) of each later change."""
    params: dict[str, float] = {}
    changes = []
    if parm is None:
        return params, changes
    for t, name, value in zip(parm["TimeUS"] * 1e-6, parm.texts("Name"), parm["Value"].tolist()):
        if name in params and params[name] != value:
            changes.append((float(t), name, float(value)))
        params[name] = float(value)
    return params, changes


def _texts(msg: Records | None) -> tuple[list[tuple[float, int, int, str]], set[int]]:
    """(t, sysid, severity, text) of each MSG (the vehicle's, or a station's, its prefix taken off), and the
    stations that wrote one."""
    texts, others = [], set()
    if msg is None:
        return texts, others
    for t, text in zip(msg["TimeUS"] * 1e-6, msg.texts("Message")):
        sysid = VEHICLE[0]
        if text.startswith("GCS:"):
            sysid, text = GCS_SYSID, text[4:]
        elif found := _SOURCE.match(text):
            sysid, text = int(found.group(1)), text[found.end():]
        if sysid != VEHICLE[0]:
            others.add(sysid)
        texts.append((float(t), sysid, mavlink.MAV_SEVERITY_INFO, text))
    return texts, others


def _arming_and_modes(r: dict[str, Records], params: dict[str, float]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t, armed, mode) at each MODE, ARM and arming EV record, in file order, from the state the log began in."""
    events = []                                      # (offset, t, kind, value)
    if (mode := r.get("MODE")) is not None:
        numbers = mode["ModeNum"] if "ModeNum" in mode else mode["Mode"]
        events += [(o, t, "mode", int(v)) for o, t, v in zip(mode.offsets, mode["TimeUS"], numbers)]
    if (arm := r.get("ARM")) is not None:
        events += [(o, t, "armed", bool(v)) for o, t, v in zip(arm.offsets, arm["TimeUS"], arm["ArmState"])]
    if (ev := r.get("EV")) is not None:
        events += [(o, t, "armed", v == EV_ARMED) for o, t, v in zip(ev.offsets, ev["TimeUS"], ev["Id"])
                   if v in (EV_ARMED, EV_DISARMED)]
    events.sort()
    arming = [value for _, _, kind, value in events if kind == "armed"]
    armed = not arming[0] if arming else not params.get("LOG_DISARMED", 0.0)
    current_mode, out = 0, []
    for _, t, kind, value in events:
        if kind == "mode":
            current_mode = value
        else:
            armed = value
        out.append((t * 1e-6, armed, current_mode))
    if not out:
        return np.zeros(0), np.zeros(0, dtype=bool), np.zeros(0, dtype=int)
    t, a, m = zip(*out)
    return np.array(t, dtype=float), np.array(a, dtype=bool), np.array(m, dtype=int)
