"""The figures of a dive that need no mission: loop timing, telemetry gaps, thruster saturation, battery, modes,
and what the vehicle's own sensors said (attitude, heading, depth, the rangefinder) with or without a position.

Pure functions of a `Dive`'s arrays. Times are vehicle seconds since boot; the log's own (wall) times are mapped
onto them through the vehicle's timestamps (`vehicle_time`).
"""

from __future__ import annotations

import re

import numpy as np

from rov_mav.flight.thrusters.actuation import PWM_TOLERANCE
from rov_mav.flight.session.link import CHANNELS, mode_name
from rov_mav.model.frames import Frame, frame_of, frames_by_string
from rov_mav.review.dive import Dive

FIRMWARE_TEXT = re.compile(r"^ArduSub V(\S+)")   # the banner's first line (`GCS_MAVLINK::send_banner`)

STALE_PERIODS = 3.0                 # the runner's watchdog: telemetry older than 3 periods is stale
PWM_LIMITS = (1100.0, 1900.0)       # us: ArduSub's SERVOn_MIN / SERVOn_MAX defaults
FRESH_WATER = 1000.0                # kg/m^3
GRAVITY = 9.80665                   # m/s^2


def vehicle_time(dive: Dive, wall: np.ndarray) -> np.ndarray:
    """Vehicle s since boot at log (wall) times: interpolated between the vehicle's timestamped messages,
    extrapolated at the log's mean rate (a vehicle at a speedup runs faster than the wall)."""
    wall = np.asarray(wall, dtype=float)
    cw, ct = dive.clock_wall, dive.clock_t
    if cw.size == 0:
        return wall - (wall.min() if wall.size else 0.0)
    rate = (ct[-1] - ct[0]) / (cw[-1] - cw[0]) if cw[-1] > cw[0] and ct[-1] > ct[0] else 1.0
    t = np.interp(wall, cw, ct)
    t = np.where(wall < cw[0], ct[0] + (wall - cw[0]) * rate, t)
    return np.where(wall > cw[-1], ct[-1] + (wall - cw[-1]) * rate, t)


def armed_window(dive: Dive) -> tuple[float, float] | None:
    """(first arming, last disarming or the log's end) in vehicle s, or None if never armed."""
    armed = np.flatnonzero(dive.armed)
    if not armed.size:
        return None
    t = vehicle_time(dive, dive.heartbeat_wall)
    after = np.flatnonzero(~dive.armed[armed[-1]:])
    end = t[armed[-1] + after[0]] if after.size else max(float(t[-1]), _last_time(dive))
    return float(t[armed[0]]), float(end)


def _last_time(dive: Dive) -> float:
    return float(dive.clock_t.max()) if dive.clock_t.size else 0.0


def telemetry(t: np.ndarray, stale_periods: float = STALE_PERIODS) -> dict:
    """State samples (ATTITUDE + LOCAL_POSITION_NED pairs) at times t (s): their rate, and the gaps longer than
    `stale_periods` typical periods (what the runner's watchdog would call stale)."""
    if t.size < 2:
        return {"samples": int(t.size), "rate_hz": float("nan"), "period_ms": float("nan"), "gaps": 0,
                "max_gap_ms": float("nan"), "stale_after_ms": float("nan"), "gap_times": []}
    dt = np.diff(t)
    period = float(np.median(dt))
    stale = stale_periods * period
    gaps = np.flatnonzero(dt > stale)
    return {"samples": int(t.size), "rate_hz": (t.size - 1) / float(t[-1] - t[0]) if t[-1] > t[0] else float("nan"),
            "period_ms": 1e3 * period, "gaps": int(gaps.size), "max_gap_ms": 1e3 * float(dt.max()),
            "stale_after_ms": 1e3 * stale, "gap_times": [(float(t[i]), float(dt[i])) for i in gaps]}


def command_rates(dive: Dive, window: tuple[float, float] | None) -> list[dict]:
    """Per station: the RC_CHANNELS_OVERRIDE, MANUAL_CONTROL and DO_MOTOR_TEST (rows of eight outputs) it sent
    (within `window`, vehicle s), and their rate in vehicle Hz."""
    streams = [(sysid, "RC_CHANNELS_OVERRIDE", wall) for sysid, (wall, _) in dive.overrides.items()]
    streams += [(sysid, "MANUAL_CONTROL", wall) for sysid, wall in dive.joysticks.items()]
    streams += [(sysid, "MAV_CMD_DO_MOTOR_TEST x 8", wall) for sysid, (wall, _) in dive.motor_tests.items()]
    out = []
    for sysid, kind, wall in sorted(streams, key=lambda s: (s[0], s[1])):
        t = vehicle_time(dive, wall)
        if window is not None:
            t = t[(t >= window[0]) & (t <= window[1])]
        span = float(t[-1] - t[0]) if t.size > 1 else 0.0
        out.append({"sysid": int(sysid), "message": kind, "count": int(t.size),
                    "rate_hz": (t.size - 1) / span if span > 0 else float("nan")})
    return out


def loop_latency(state_wall: np.ndarray, command_wall: np.ndarray) -> np.ndarray:
    """ms from each state's arrival to the first command sent after it and before the next state (the log's own
    clock: meaningful when the log was written by the station that sent the commands)."""
    if state_wall.size == 0 or command_wall.size == 0:
        return np.zeros(0)
    commands = np.sort(command_wall)
    k = np.searchsorted(commands, state_wall, side="left")
    has = k < commands.size
    following = np.where(has, commands[np.minimum(k, commands.size - 1)], np.inf)
    next_state = np.append(state_wall[1:], np.inf)
    answered = has & (following < next_state)
    return 1e3 * (following[answered] - state_wall[answered])


def pwm_limits(params: dict[str, float]) -> tuple[np.ndarray, np.ndarray]:
    """(low (8,), high (8,)) us: SERVO1..8_MIN / _MAX as the vehicle reported them, else ArduSub's defaults."""
    low = np.array([params.get(f"SERVO{n}_MIN", PWM_LIMITS[0]) for n in range(1, CHANNELS + 1)])
    high = np.array([params.get(f"SERVO{n}_MAX", PWM_LIMITS[1]) for n in range(1, CHANNELS + 1)])
    return low, high


def saturation(pwm: np.ndarray, low: np.ndarray, high: np.ndarray) -> dict:
    """How often each of the 8 outputs (M, 8) us sat at its limits (within the runner's PWM tolerance); 0 us
    (an output not driven) does not count."""
    pwm = np.asarray(pwm, dtype=float).reshape(-1, CHANNELS)
    driven = np.isfinite(pwm) & (pwm > 0)
    at_limit = driven & ((pwm <= low + PWM_TOLERANCE) | (pwm >= high - PWM_TOLERANCE))
    counts = np.maximum(driven.sum(axis=0), 1)
    any_row = at_limit.any(axis=1)
    return {"samples": int(pwm.shape[0]), "fraction_at_limit": [float(v) for v in at_limit.sum(axis=0) / counts],
            "fraction_any_at_limit": float(any_row.mean()) if any_row.size else 0.0}


def battery(dive: Dive) -> dict:
    """Voltage at the start, lowest (and when, vehicle s), at the end; mAh consumed (BATTERY_STATUS, else the
    current integrated); NaN for what the vehicle did not report."""
    t = vehicle_time(dive, dive.power_wall)
    v = dive.voltage
    ok = np.isfinite(v)
    out = {"start_v": float("nan"), "min_v": float("nan"), "min_at_s": float("nan"), "end_v": float("nan"),
           "consumed_mah": float("nan"), "consumed_from": None}
    if ok.any():
        i = int(np.flatnonzero(ok)[np.argmin(v[ok])])
        out.update(start_v=float(v[ok][0]), min_v=float(v[i]), min_at_s=float(t[i]), end_v=float(v[ok][-1]))
    mah = dive.consumed_mah[np.isfinite(dive.consumed_mah)]
    current = np.isfinite(dive.current)
    if mah.size:
        out.update(consumed_mah=float(mah[-1] - mah[0]), consumed_from="BATTERY_STATUS")
    elif current.sum() > 1:
        tc, a = t[current], dive.current[current]
        out.update(consumed_mah=float(np.sum(0.5 * (a[1:] + a[:-1]) * np.diff(tc)) / 3.6),
                   consumed_from="SYS_STATUS current")
    return out


def mode_changes(dive: Dive) -> list[tuple[float, str]]:
    """(vehicle s, text): the first HEARTBEAT's state, then every change of arming or mode."""
    t = vehicle_time(dive, dive.heartbeat_wall)
    out, last = [], None
    for ti, armed, mode in zip(t, dive.armed, dive.mode):
        if last is None:
            out.append((float(ti), f"{'armed' if armed else 'disarmed'}, {mode_name(int(mode))}"))
        elif armed != last[0]:
            out.append((float(ti), f"{'armed' if armed else 'disarmed'} ({mode_name(int(mode))})"))
        elif mode != last[1]:
            out.append((float(ti), f"mode {mode_name(int(mode))}"))
        last = (armed, mode)
    return out


def dive_depth(dive: Dive) -> tuple[np.ndarray, np.ndarray, str] | None:
    """(log times, depth m, how), in this order of trust: the Bar30 (SCALED_PRESSURE2's press_abs, hPa) against the
    surface pressure the vehicle calibrated at boot (BARO2_GND_PRESS, Pa): depth = (p - p_surface) / (rho g), rho =
    FRESH_WATER x BARO_SPEC_GRAV (ArduSub's fluid: 1.0 fresh, 1.024 salt); else ArduSub's own altitude, negated
    (GLOBAL_POSITION_INT.relative_alt; CTUN.Alt in a DataFlash log): a log trimmed of its parameters or started
    mid-dive has no surface in it; else the Bar30 against the log's lowest pressure (the vehicle at the surface at
    some point); None without any."""
    ground = dive.params.get("BARO2_GND_PRESS")
    if not (ground and dive.pressure_wall.size) and dive.altitude_wall.size:
        return dive.altitude_wall, -dive.altitude, "ArduSub's own altitude (GLOBAL_POSITION_INT / CTUN.Alt)"
    if not dive.pressure_wall.size:
        return None
    pascal = dive.pressure_abs * 100.0
    how = "BARO2_GND_PRESS" if ground else "the log's lowest pressure"
    surface = float(ground) if ground else float(np.nanmin(pascal))
    density = FRESH_WATER * dive.params.get("BARO_SPEC_GRAV", 1.0)
    depth = (pascal - surface) / (density * GRAVITY)
    return dive.pressure_wall, depth, f"Bar30 (SCALED_PRESSURE2), surface pressure {how}"


def identity(dive: Dive) -> dict:
    """Which ArduSub, on which frame: the firmware the banner named ("ArduSub V4.1.0 (...)"), the frame by
    FRAME_CONFIG or, without the parameter, the banner's "Frame: ..." line (`logged_frame`); each None when the log
    does not say."""
    texts = _vehicle_texts(dive)
    firmware = next((found.group(1) for text in texts if (found := FIRMWARE_TEXT.match(text))), None)
    frames, banner = logged_frames(dive)
    if "FRAME_CONFIG" in dive.params:
        frame = frames[0].describe()
    elif banner is not None:
        frame = f"{banner} ({frames[0].motors} motors)" if frames else banner
    else:
        frame = None
    return {"firmware": firmware, "frame": frame}


def logged_frames(dive: Dive) -> tuple[list[Frame], str | None]:
    """The frames the log's vehicle may be on, and its banner's "Frame: ..." line (None without one): FRAME_CONFIG's
    frame, else those whose frame string the banner names (`GCS_MAVLINK_Sub::send_banner`); none when neither says."""
    banner = next((text.strip() for text in _vehicle_texts(dive) if text.startswith("Frame:")), None)
    if "FRAME_CONFIG" in dive.params:
        return [frame_of(int(dive.params["FRAME_CONFIG"]))], banner
    return (frames_by_string(banner.removeprefix("Frame:").strip()) if banner else []), banner


def _vehicle_texts(dive: Dive) -> list[str]:
    vehicle = dive.vehicle[0] if dive.vehicle else None
    return [text for _, sysid, _, text in dive.texts if sysid == vehicle]


def own_sensors(dive: Dive) -> dict:
    """What the vehicle's own sensors said, position or not: attitude and heading (ATTITUDE), depth (the Bar30),
    the distance above the bottom (a downward rangefinder); each block present only if the log has it."""
    out: dict = {}
    if dive.attitude.size:
        roll, pitch, yaw = (np.degrees(dive.attitude[:, i]) for i in range(3))
        tilt = np.degrees(np.arccos(np.clip(np.cos(dive.attitude[:, 0]) * np.cos(dive.attitude[:, 1]), -1, 1)))
        out["attitude"] = {"samples": int(roll.size), "roll_rms_deg": float(np.sqrt(np.mean(roll ** 2))),
                           "pitch_rms_deg": float(np.sqrt(np.mean(pitch ** 2))), "max_tilt_deg": float(tilt.max()),
                           "heading_start_deg": float(yaw[0] % 360), "heading_end_deg": float(yaw[-1] % 360)}
    depth = dive_depth(dive)
    if depth is not None:
        _, d, how = depth
        out["depth"] = {"samples": int(d.size), "min_m": float(np.nanmin(d)), "mean_m": float(np.nanmean(d)),
                        "max_m": float(np.nanmax(d)), "source": how}
    if dive.range_m.size:
        r = dive.range_m
        out["rangefinder"] = {"samples": int(r.size), "min_m": float(r.min()), "mean_m": float(r.mean()),
                              "max_m": float(r.max())}
    return out


def bottom_profile(dive: Dive, speed: float, spacing: float = 0.1) -> np.ndarray | None:
    """The bottom's depth along a line, rebuilt from a dive's depth plus its down-looking rangefinder's readings:
    (K, 2) [distance m, depth m], the median of the soundings in each `spacing` m; None without both. A log holds
    no horizontal position without a position source, so the soundings are laid along a line in the order they came,
    `speed` m/s of the time since the first (as a transect flown at that speed): the profile is the bottom the
    vehicle saw, in time, not a survey of where it was."""
    depth = dive_depth(dive)
    if depth is None or not dive.range_m.size:
        return None
    wall, d, _ = depth
    known = np.isfinite(d)
    bottom = np.interp(dive.range_wall, wall[known], d[known]) + dive.range_m
    distance = speed * (dive.range_wall - dive.range_wall[0])
    bins = np.floor(distance / spacing).astype(int)
    edges = np.flatnonzero(np.diff(bins)) + 1
    groups = np.split(np.arange(bins.size), edges)
    return np.array([[bins[g[0]] * spacing, float(np.median(bottom[g]))] for g in groups])
