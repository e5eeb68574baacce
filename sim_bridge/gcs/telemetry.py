"""Telemetry messages as ArduSub fills them, built from a snapshot of the simulated vehicle.

Every time field is simulated time since boot. Position, velocity and attitude are the autopilot's estimate
(`sim_bridge.navigation.aiding`: the plant's measured, noisy state while every sensor works); depth comes from the Bar30
(SCALED_PRESSURE2: its last reading, frozen, once it has failed; not sent when it was not found at boot); LOCAL
position only while the EKF has one (a builder returning None sends nothing), GLOBAL position always (stale if need
be); EKF_STATUS_REPORT the EKF's flags and variances. SYS_STATUS (`GCS_Sub::update_sensor_status_flags`): the depth
sensor's ABSOLUTE_PRESSURE bit present when found at boot and healthy while it works, the battery unhealthy once its
failsafe has triggered, gyro and accelerometers neither enabled nor healthy until initialised; BATTERY_STATUS's
charge state LOW / CRITICAL with the battery failsafe (`AP_BattMonitor::get_mavlink_charge_state`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from rov_mav.model.dynamics import rotation
from rov_mav.model.frames import Frame
from rov_mav.units import wrap_angle

ENCODER = mavlink.MAVLink(None)
EARTH_RADIUS = 6378137.0                 # m
SURFACE_PRESSURE = 101325.0              # Pa
WATER_TEMPERATURE = 15.0                 # deg C
FIRMWARE_VERSION = {"4.5": (4, 5, 7), "4.7": (4, 7, 2)}
SIM_HEIGHT_NAMES = ("SimHeight", "SimIceGap")   # NAMED_VALUE_FLOAT names of the true heights (`sim_heights`)
GIT_HASH = "00000000"          # flight_custom_version and the banner's hash: an emulator has no build to name
SENSORS = (mavlink.MAV_SYS_STATUS_SENSOR_3D_GYRO | mavlink.MAV_SYS_STATUS_SENSOR_3D_ACCEL
           | mavlink.MAV_SYS_STATUS_SENSOR_3D_MAG | mavlink.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
           | mavlink.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS | mavlink.MAV_SYS_STATUS_AHRS
           | mavlink.MAV_SYS_STATUS_SENSOR_BATTERY)
HEALTH = SENSORS | mavlink.MAV_SYS_STATUS_GEOFENCE   # no fence, and so no breach
INERTIAL = mavlink.MAV_SYS_STATUS_SENSOR_3D_GYRO | mavlink.MAV_SYS_STATUS_SENSOR_3D_ACCEL
CAPABILITIES = (mavlink.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT | mavlink.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
                | mavlink.MAV_PROTOCOL_CAPABILITY_MAVLINK2 | mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_FLOAT
                | mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_INT)
MISSION_STATE_NO_MISSION, MISSION_STATE_NOT_STARTED = 1, 2   # MISSION_STATE (common.xml)


@dataclass
class Snapshot:
    """What the telemetry reports at one instant. Arrays: eta, nu (6,), servo (16,), rc_in (16,)."""

    t_us: int                            # simulated time since boot, microseconds (exact: steps x step)
    eta: np.ndarray
    nu: np.ndarray
    servo: np.ndarray
    rc_in: np.ndarray
    base_mode: int
    custom_mode: int
    system_status: int
    throttle: float                      # pilot throttle axis, -1..1
    voltage: float                       # V
    current: float                       # A
    consumed_ah: float
    remaining: float                     # 0..1
    origin: tuple[float, float, float]   # lat deg, lon deg, alt m (surface)
    water_density: float
    gravity: float
    unix_start: float                    # wall-clock epoch (s) of simulated time 0
    firmware: str
    mission_count: int = 0               # items of the stored mission, home's slot included
    mission_current: tuple[int, int] = (0, MISSION_STATE_NOT_STARTED)  # (seq, MISSION_STATE) of AUTO's mission
    safety_on: bool = False              # the software safety switch: motor outputs not enabled
    initialised: bool = True             # `ap.initialised`
    local_position: bool = True          # the EKF has a horizontal position (LOCAL_POSITION_NED is sent)
    ekf_flags: int = 831                 # EKF_STATUS_REPORT flags
    ekf_variances: tuple[float, float, float, float] = (0.05, 0.05, 0.05, 0.05)  # velocity, pos h, pos v, compass
    battery_state: int = 0               # 0 none, 1 low, 2 critical (the battery failsafe)
    battery_failsafed: bool = False
    depth_present: bool = True           # the depth sensor found at boot
    depth_healthy: bool = True
    bar30_depth: float | None = None     # m, what the depth sensor reads (None: the estimate's depth)
    truth: tuple[np.ndarray, np.ndarray] | None = None   # the plant's (eta, nu), for SIM_STATE
    truth_heights: tuple[float | None, float | None] = (None, None)   # m: true height above the bottom, below the ice
    rangefinder: tuple | None = None     # (distance m, min m, max m, orientation, quality -1..100, MAV type) with data
    rangefinder_target: float = -0.01    # m: SURFTRAK's range target (-0.01: none, ArduSub's -1 cm)
    rangefinder_log: tuple | None = None # (distance m, status, orientation, quality) with a backend, for RFND
    targets: tuple[float, float, float, float] = (math.nan,) * 4   # held roll, pitch, yaw (rad), depth (m); NaN: none

    @property
    def ms(self) -> int:
        return (self.t_us // 1000) & 0xFFFFFFFF

    def ned_velocity(self) -> np.ndarray:
        return rotation(self.eta) @ self.nu[:3]


def quaternion(phi: float, theta: float, psi: float) -> tuple[float, float, float, float]:
    """(w, x, y, z) of the ZYX Euler angles."""
    cr, sr = math.cos(phi / 2), math.sin(phi / 2)
    cp, sp = math.cos(theta / 2), math.sin(theta / 2)
    cy, sy = math.cos(psi / 2), math.sin(psi / 2)
    return (cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy)


def heartbeat(s: Snapshot):
    return ENCODER.heartbeat_encode(mavlink.MAV_TYPE_SUBMARINE, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA,
                                    s.base_mode, s.custom_mode, s.system_status, 3)


def attitude(s: Snapshot):
    """Roll, pitch and yaw within [-pi, pi), as ArduPilot's AHRS reports them (the plant's angles accumulate turns:
    a yaw of -4.08 rad reached a station before this, found by tests/test_bridge_fuzz.py)."""
    return ENCODER.attitude_encode(s.ms, *map(float, wrap_angle(s.eta[3:6])), *map(float, s.nu[3:6]))


def attitude_quaternion(s: Snapshot):
    return ENCODER.attitude_quaternion_encode(s.ms, *quaternion(*s.eta[3:6]), *map(float, s.nu[3:6]))


def local_position_ned(s: Snapshot):
    if not s.local_position:
        return None
    return ENCODER.local_position_ned_encode(s.ms, *map(float, s.eta[:3]), *map(float, s.ned_velocity()))


def global_position_int(s: Snapshot):
    lat0, lon0, alt0 = s.origin
    x, y, z = s.eta[:3]
    lat = lat0 + math.degrees(x / EARTH_RADIUS)
    lon = lon0 + math.degrees(y / (EARTH_RADIUS * math.cos(math.radians(lat0))))
    v = s.ned_velocity() * 100.0
    return ENCODER.global_position_int_encode(
        s.ms, round(lat * 1e7), round(lon * 1e7), round((alt0 - z) * 1000), round(-z * 1000),
        round(v[0]), round(v[1]), round(v[2]), round(math.degrees(s.eta[5]) % 360.0 * 100) % 36000)


def gauge_pressure(s: Snapshot) -> float:
    """Water pressure above the surface's at the Bar30, Pa."""
    depth = s.eta[2] if s.bar30_depth is None else s.bar30_depth
    return s.water_density * s.gravity * float(depth)


def scaled_pressure2(s: Snapshot):
    if not s.depth_present:              # `send_scaled_pressure_instance`: no second barometer, no message
        return None
    diff = gauge_pressure(s)
    return ENCODER.scaled_pressure2_encode(s.ms, (SURFACE_PRESSURE + diff) / 100.0, diff / 100.0,
                                           round(WATER_TEMPERATURE * 100))


def vfr_hud(s: Snapshot):
    v = s.ned_velocity()
    speed = float(math.hypot(v[0], v[1]))
    heading = round(math.degrees(s.eta[5])) % 360
    return ENCODER.vfr_hud_encode(speed, speed, heading, round(abs(s.throttle) * 100), -float(s.eta[2]),
                                  -float(v[2]))


def servo_output_raw(s: Snapshot):
    return ENCODER.servo_output_raw_encode(s.t_us & 0xFFFFFFFF, 0, *map(int, s.servo))


def rc_channels(s: Snapshot):
    values = [*map(int, s.rc_in), 0, 0]            # channels 17 and 18 do not exist in ArduPilot
    return ENCODER.rc_channels_encode(s.ms, len(s.rc_in), *values, 255)


def sys_status(s: Snapshot):
    present = SENSORS if s.depth_present else SENSORS & ~mavlink.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
    enabled = present & ~mavlink.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS if s.safety_on else present
    health = HEALTH & present
    if not s.depth_healthy:
        health &= ~mavlink.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
    if s.battery_failsafed:
        health &= ~mavlink.MAV_SYS_STATUS_SENSOR_BATTERY
    if not s.initialised:
        enabled &= ~INERTIAL
        health &= ~INERTIAL
    return ENCODER.sys_status_encode(present, enabled, health, 0, round(s.voltage * 1000), round(s.current * 100),
                                     round(s.remaining * 100), 0, 0, 0, 0, 0, 0)


CHARGE_STATE = {0: mavlink.MAV_BATTERY_CHARGE_STATE_OK, 1: mavlink.MAV_BATTERY_CHARGE_STATE_LOW,
                2: mavlink.MAV_BATTERY_CHARGE_STATE_CRITICAL}


def battery_status(s: Snapshot):
    cells = [round(s.voltage * 1000)] + [65535] * 9
    return ENCODER.battery_status_encode(0, mavlink.MAV_BATTERY_FUNCTION_UNKNOWN, mavlink.MAV_BATTERY_TYPE_LION,
                                         32767, cells, round(s.current * 100), round(s.consumed_ah * 1000), -1,
                                         round(s.remaining * 100), 0, CHARGE_STATE[s.battery_state])


def ekf_status_report(s: Snapshot):
    """NavEKF3_core::send_status_report: the flags and variances (terrain and airspeed 0: no rangefinder, no
    airspeed)."""
    return ENCODER.ekf_status_report_encode(s.ekf_flags, *map(float, s.ekf_variances), 0.0, 0.0)


def system_time(s: Snapshot):
    return ENCODER.system_time_encode(int(s.unix_start * 1e6) + s.t_us, s.ms)


def autopilot_version(s: Snapshot):
    major, minor, patch = FIRMWARE_VERSION[s.firmware]
    version = (major << 24) | (minor << 16) | (patch << 8) | mavlink.FIRMWARE_VERSION_TYPE_OFFICIAL
    return ENCODER.autopilot_version_encode(CAPABILITIES, version, 0, 0, 0, list(GIT_HASH.encode()), [0] * 8,
                                            [0] * 8, 0, 0, 0)


def banner(firmware: str, frame: Frame) -> list[str]:
    """The STATUSTEXTs (INFO) of `GCS_MAVLINK::send_banner`, as SITL sends them (no OS or board lines): the firmware
    string (THISFIRMWARE " (" GIT_VERSION ")"), then Sub's "Frame: " and the frame string of the frame it booted with
    (`GCS_MAVLINK_Sub::send_banner`, `AP_Motors6DOF::setup_motors`)."""
    return [firmware_string(firmware), f"Frame: {frame.name}"]


def firmware_string(firmware: str) -> str:
    """THISFIRMWARE " (" GIT_VERSION ")": the banner's first line."""
    major, minor, patch = FIRMWARE_VERSION[firmware]
    return f"ArduSub V{major}.{minor}.{patch} ({GIT_HASH})"


def mission_current(s: Snapshot):
    """As ArduSub streams it (`GCS_MAVLINK::send_mission_current`, `mission_state`): the current navigation
    command (0 before any), total = items past home, no mission until one is stored past home, else AUTO's mission
    not started, active or complete (`sim_bridge.modes.auto`)."""
    seq, state = s.mission_current
    if s.mission_count <= 1:
        state = MISSION_STATE_NO_MISSION
    return ENCODER.mission_current_encode(seq, max(s.mission_count - 1, 0), state, 0)


def home_position(s: Snapshot):
    lat0, lon0, alt0 = s.origin
    return ENCODER.home_position_encode(round(lat0 * 1e7), round(lon0 * 1e7), round(alt0 * 1000), 0.0, 0.0, 0.0,
                                        [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0, s.t_us)


def _latlon(origin: tuple[float, float, float], north: float, east: float) -> tuple[float, float]:
    lat0, lon0, _ = origin
    return (lat0 + math.degrees(north / EARTH_RADIUS),
            lon0 + math.degrees(east / (EARTH_RADIUS * math.cos(math.radians(lat0)))))


def sim_state(s: Snapshot):
    """The simulator's truth as ArduPilot SITL reports it (`SIM::sim_state_send`): attitude (quaternion and
    Euler, yaw within +-pi), body specific force (here gravity only: the plant's acceleration is not kept), body
    rates, lat/lon as SITL fills them (the float fields carry degE7, and the int extensions too), altitude above sea
    level (the origin's altitude less the depth), standard deviations 0, NED velocity."""
    if s.truth is None:
        return None
    eta, nu = s.truth
    phi, theta, psi = (float(a) for a in wrap_angle(eta[3:6]))
    r = rotation(eta)
    accel = r.T @ np.array([0.0, 0.0, -s.gravity])
    v = r @ nu[:3]
    lat, lon = _latlon(s.origin, float(eta[0]), float(eta[1]))
    return ENCODER.sim_state_encode(*quaternion(phi, theta, psi), phi, theta, psi, *map(float, accel),
                                    *map(float, nu[3:6]), lat * 1e7, lon * 1e7, float(s.origin[2] - eta[2]), 0.0,
                                    0.0, *map(float, v), round(lat * 1e7), round(lon * 1e7))


def sim_heights(s: Snapshot) -> list:
    """The truth beside SIM_STATE where the water has a bottom or an ice ceiling (the built-in vehicle's own: no
    ArduPilot SITL sends these): NAMED_VALUE_FLOAT "SimHeight", the true height of the vehicle's origin above the
    bottom straight below it, and "SimIceGap", the true distance below the ice straight above, in m."""
    return [ENCODER.named_value_float_encode(s.ms, name.encode(), float(value))
            for name, value in zip(SIM_HEIGHT_NAMES, s.truth_heights) if value is not None]


def distance_sensor(s: Snapshot):
    """The autopilot's own DISTANCE_SENSOR of its rangefinder while it has data (`GCS_MAVLINK::send_distance_sensor`,
    a MAVLink-fed one re-sent too): cm capped at 65535, id 0 (the instance), covariance and fovs 0, quality -1 sent
    as 0, 0 and 1 as 1."""
    if s.rangefinder is None:
        return None
    distance, low, high, orientation, quality, kind = s.rangefinder
    cm = [min(round(v * 100), 65535) for v in (low, high, distance)]
    sent = 0 if quality < 0 else 1 if quality <= 1 else quality
    return ENCODER.distance_sensor_encode(s.ms, *cm, kind, 0, orientation, 0, 0.0, 0.0, [0.0, 0.0, 0.0, 0.0], sent)


def rangefinder(s: Snapshot):
    """RANGEFINDER (`GCS_MAVLINK::send_rangefinder`): the downward rangefinder's distance in m, voltage 0; streamed in
    4.5's EXTRA3, only when asked for in 4.7 (PR #31095 took it out of the streams)."""
    if s.rangefinder is None:
        return None
    return ENCODER.rangefinder_encode(float(s.rangefinder[0]), 0.0)


def named_value_float(s: Snapshot):
    """`GCS_MAVLINK_Sub::send_info`'s "RFTarget": SURFTRAK's range target in m (-0.01 without one), in every mode
    (of its batch of named values, the only one emulated)."""
    return ENCODER.named_value_float_encode(s.ms, b"RFTarget", float(s.rangefinder_target))


def gps_global_origin(s: Snapshot):
    """The EKF origin (`GCS_MAVLINK::send_gps_global_origin`): `--origin`, altitude in mm."""
    lat0, lon0, alt0 = s.origin
    return ENCODER.gps_global_origin_encode(round(lat0 * 1e7), round(lon0 * 1e7), round(alt0 * 1000), s.t_us)


BUILDERS = {
    "HEARTBEAT": heartbeat,
    "ATTITUDE": attitude,
    "ATTITUDE_QUATERNION": attitude_quaternion,
    "LOCAL_POSITION_NED": local_position_ned,
    "GLOBAL_POSITION_INT": global_position_int,
    "SCALED_PRESSURE2": scaled_pressure2,
    "VFR_HUD": vfr_hud,
    "SERVO_OUTPUT_RAW": servo_output_raw,
    "RC_CHANNELS": rc_channels,
    "SYS_STATUS": sys_status,
    "BATTERY_STATUS": battery_status,
    "EKF_STATUS_REPORT": ekf_status_report,
    "SYSTEM_TIME": system_time,
    "AUTOPILOT_VERSION": autopilot_version,
    "HOME_POSITION": home_position,
    "MISSION_CURRENT": mission_current,
    "SIM_STATE": sim_state,
    "DISTANCE_SENSOR": distance_sensor,
    "RANGEFINDER": rangefinder,
    "NAMED_VALUE_FLOAT": named_value_float,
    "GPS_GLOBAL_ORIGIN": gps_global_origin,
}
NAME_OF_ID = {getattr(mavlink, f"MAVLINK_MSG_ID_{name}"): name for name in BUILDERS}
