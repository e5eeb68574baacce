"""ArduSub's parameters that the bridge uses: names, defaults and MAVLink types, for firmware 4.5 or 4.7 naming.

ArduSub 4.7 renamed SYSID_MYGCS -> MAV_GCS_SYSID, SYSID_THISMAV -> MAV_SYSID and the stream rates SRn_* (n from 0)
-> MAV{n+1}_*, and SYSID_ENFORCE -> MAV_OPTIONS bit 0 (PR #29617, `GCS_MAVLink_Parameters.cpp`); it added
MAV_GCS_SYSID_HI (PR #30627: every sysid from MAV_GCS_SYSID to it is a GCS, `GCS::sysid_is_gcs`) and MAVn_OPTIONS
(bit 1: the link neither forwards nor is forwarded to, `sim_bridge.gcs.routing`; bit 2: REQUEST_DATA_STREAM ignored).
`Params(firmware)` holds one of the two name sets; `Params.names` maps the roles the bridge reads to the names that
firmware uses. SIM_* are the simulation's own settings (as in ArduPilot's SITL).

Each value is also kept as stored (the flight controller's EEPROM): a PARAM_SET stores what it sets
(GCS_Param.cpp, `handle_param_set` saves), a REQUEST_DATA_STREAM only sets the rate in RAM (`handle_request_data_stream`
saves only when `persist_streamrates()`, which Sub does not override: false), and `reboot()` loads the stored values.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from rov_mav.model.frames import HEAVY, MOTOR_FUNCTION_BASE, frame_of
from sim_bridge.autopilot.arming import RC_OPTION_ARMING_CHECK_THROTTLE, SUB_CHECKS
from sim_bridge.autopilot.buttons import BUTTONS, DEFAULTS
from sim_bridge.hardware.numeric import f32, float_to_int

INT8, INT16, INT32, REAL32 = 2, 4, 6, 9          # MAV_PARAM_TYPE
_LIMITS = {INT8: (-128, 127), INT16: (-32768, 32767), INT32: (-2**31, 2**31 - 1)}
_ROUNDING = f32(0.01)

FIRMWARES = ("4.5", "4.7")
DEFAULT_FIRMWARE = "4.7"
BUILT_IN_FRAME = HEAVY.config    # the built-in vehicle is a BlueROV2 Heavy unless told FRAME_CONFIG (ArduSub's own
                                 # default is 1, VECTORED: a vehicle set up as a Heavy has it 2)
CHANNELS = 4                                     # MAVLink channels (links) that have stream-rate parameters
NO_FORWARD, NO_STREAM_OVERRIDE = 1 << 1, 1 << 2  # MAVn_OPTIONS bits (4.7, `GCS_MAVLINK::var_info`)
GCS_SYSID_ENFORCE = 1 << 0                       # MAV_OPTIONS bit (4.7; SYSID_ENFORCE in 4.5)
STREAM_GROUPS = ("RAW_SENS", "EXT_STAT", "RC_CHAN", "RAW_CTRL", "POSITION",
                 "EXTRA1", "EXTRA2", "EXTRA3", "PARAMS", "ADSB")
# Stream rates in Hz: ATTITUDE 10, position 3, servo/status 2 as measured on ArduSub SITL; the rest chosen.
STREAM_DEFAULTS = {"RAW_SENS": 2, "EXT_STAT": 2, "RC_CHAN": 2, "RAW_CTRL": 0, "POSITION": 3,
                   "EXTRA1": 10, "EXTRA2": 10, "EXTRA3": 3, "PARAMS": 0, "ADSB": 0}


# GUIDED's position and attitude controllers (`sim_bridge.modes.guided`), by their 4.5 names and units: ArduSub
# 4.5.3's
# defaults, read from its SITL. WPNAV_SPEED is AUTO's leg speed (read by a run flying the vehicle's mission), and
# WPNAV_RADIUS its waypoints' radius (AC_WPNav's default, 2 m; `sim_bridge.modes.wpnav`).
GUIDED_DEFAULTS = {
    "WPNAV_SPEED": 100.0, "WPNAV_RADIUS": 200.0,
    "ANGLE_MAX": 4500.0,                                                 # cd
    "WPNAV_ACCEL": 250.0, "WPNAV_SPEED_UP": 250.0, "WPNAV_SPEED_DN": 150.0, "WPNAV_ACCEL_Z": 100.0,   # cm/s, cm/s/s
    "PSC_POSXY_P": 1.0, "PSC_VELXY_P": 6.0, "PSC_VELXY_I": 0.5, "PSC_VELXY_D": 0.0, "PSC_VELXY_IMAX": 1000.0,
    "PSC_VELXY_FLTE": 5.0, "PSC_VELXY_FLTD": 5.0,
    "PSC_POSZ_P": 3.0, "PSC_VELZ_P": 8.0,
    "PSC_ACCZ_P": 0.5, "PSC_ACCZ_I": 0.1, "PSC_ACCZ_D": 0.0, "PSC_ACCZ_IMAX": 100.0, "PSC_ACCZ_FLTE": 20.0,
    "ATC_ANG_RLL_P": 6.0, "ATC_ANG_PIT_P": 6.0, "ATC_ANG_YAW_P": 6.0, "ATC_RATE_Y_MAX": 180.0,        # deg/s
    "ATC_RAT_RLL_P": 0.135, "ATC_RAT_RLL_I": 0.09, "ATC_RAT_RLL_D": 0.0036, "ATC_RAT_RLL_IMAX": 0.444,
    "ATC_RAT_PIT_P": 0.135, "ATC_RAT_PIT_I": 0.09, "ATC_RAT_PIT_D": 0.0036, "ATC_RAT_PIT_IMAX": 0.444,
    "ATC_RAT_YAW_P": 0.18, "ATC_RAT_YAW_I": 0.018, "ATC_RAT_YAW_D": 0.0, "ATC_RAT_YAW_IMAX": 0.222,
}


# 4.7's names and units of those of them it renamed: (4.7 name, 4.5 units per 4.7 unit). AC_PosControl's
# `convert_parameters` (PSC_POSXY -> PSC_NE_POS, PSC_VELXY -> PSC_NE_VEL with IMAX in m/s/s, PSC_POSZ -> PSC_D_POS,
# PSC_VELZ -> PSC_D_VEL, PSC_ACCZ -> PSC_D_ACC with P, I, D x 0.1 and IMAX x 0.001), AC_WPNav (WPNAV_ -> WP_, cm ->
# m: PR #32147), AC_AttitudeControl (ANGLE_MAX in cd -> ATC_ANGLE_MAX in degrees). The ATC_ANG_* and ATC_RAT_* gains
# kept their names.
RENAMED_IN_4_7 = {
    "ANGLE_MAX": ("ATC_ANGLE_MAX", 100.0),
    "WPNAV_SPEED": ("WP_SPD", 100.0), "WPNAV_ACCEL": ("WP_ACC", 100.0), "WPNAV_SPEED_UP": ("WP_SPD_UP", 100.0),
    "WPNAV_RADIUS": ("WP_RADIUS_M", 100.0),
    "WPNAV_SPEED_DN": ("WP_SPD_DN", 100.0), "WPNAV_ACCEL_Z": ("WP_ACC_Z", 100.0),
    "PSC_POSXY_P": ("PSC_NE_POS_P", 1.0), "PSC_VELXY_P": ("PSC_NE_VEL_P", 1.0), "PSC_VELXY_I": ("PSC_NE_VEL_I", 1.0),
    "PSC_VELXY_D": ("PSC_NE_VEL_D", 1.0), "PSC_VELXY_IMAX": ("PSC_NE_VEL_IMAX", 100.0),
    "PSC_VELXY_FLTE": ("PSC_NE_VEL_FLTE", 1.0), "PSC_VELXY_FLTD": ("PSC_NE_VEL_FLTD", 1.0),
    "PSC_POSZ_P": ("PSC_D_POS_P", 1.0), "PSC_VELZ_P": ("PSC_D_VEL_P", 1.0),
    "PSC_ACCZ_P": ("PSC_D_ACC_P", 10.0), "PSC_ACCZ_I": ("PSC_D_ACC_I", 10.0), "PSC_ACCZ_D": ("PSC_D_ACC_D", 10.0),
    "PSC_ACCZ_IMAX": ("PSC_D_ACC_IMAX", 1000.0), "PSC_ACCZ_FLTE": ("PSC_D_ACC_FLTE", 1.0),
}


def renamed(name: str, value: float, is_4_7: bool) -> tuple[str, float]:
    """A GUIDED parameter's (name, default) on the firmware: 4.5's, or 4.7's name and units."""
    if not is_4_7 or name not in RENAMED_IN_4_7:
        return name, value
    new, scale = RENAMED_IN_4_7[name]
    return new, value / scale


@dataclass(frozen=True)
class Spec:
    name: str
    default: float
    ptype: int


@dataclass(frozen=True)
class Names:
    """The parameter names of one firmware version for the roles the bridge reads."""

    gcs_sysid: str
    sysid: str
    stream_prefix: tuple[str, ...]   # per channel, e.g. ("SR0_", ...) or ("MAV1_", ...)

    def stream(self, channel: int, group: str) -> str:
        """The rate parameter of `group` on link `channel`; links past the last set share it."""
        return f"{self.stream_prefix[min(channel, CHANNELS - 1)]}{group}"


def names_for(firmware: str) -> Names:
    """Parameter names used by ArduSub `firmware` ("4.5" or "4.7")."""
    if firmware == "4.5":
        return Names("SYSID_MYGCS", "SYSID_THISMAV", tuple(f"SR{n}_" for n in range(CHANNELS)))
    if firmware == "4.7":
        return Names("MAV_GCS_SYSID", "MAV_SYSID", tuple(f"MAV{n + 1}_" for n in range(CHANNELS)))
    raise ValueError(f"unknown firmware {firmware!r}: choose one of {', '.join(FIRMWARES)}")


def _table(names: Names, frame: int) -> list[Spec]:
    specs = [
        Spec(names.sysid, 1, INT16),
        Spec(names.gcs_sysid, 255, INT16),
        *([Spec("MAV_GCS_SYSID_HI", 0, INT16), Spec("MAV_OPTIONS", 0, INT16)] if names.sysid == "MAV_SYSID"
          else [Spec("SYSID_ENFORCE", 0, INT8)]),
        # the arming checks (`sim_bridge.autopilot.arming`): 4.7 the checks skipped, 4.5 the checks performed; Sub's
        # defaults
        # run RC, voltage and battery only (ArduSub/Parameters.h defaults table)
        Spec("ARMING_SKIPCHK", ~SUB_CHECKS, INT32) if names.sysid == "MAV_SYSID"
        else Spec("ARMING_CHECK", SUB_CHECKS, INT32),
        Spec("RC_OPTIONS", RC_OPTION_ARMING_CHECK_THROTTLE, INT32),   # RC_Channels_VarInfo's default
        *([Spec("THR_ARM_POS", 1, INT8)] if names.sysid == "MAV_SYSID" else []),   # 4.7: throttle centred to arm
        Spec("FRAME_CONFIG", frame, INT8),             # read at boot (`rov_mav.model.frames`)
        Spec("MOT_FV_CPLNG_K", 1.0, REAL32),           # the VECTORED frame's forward/vertical coupling
        Spec("MOT_PWM_MIN", 1100, INT16),
        Spec("MOT_PWM_MAX", 1900, INT16),
        *(Spec(f"MOT_{i}_DIRECTION", 1, INT8) for i in range(1, 9)),
        Spec("RC_OVERRIDE_TIME", 3.0, REAL32),
        # The pilot's joystick (MANUAL_CONTROL), defaults measured on ArduSub 4.5.3 SITL.
        Spec("JS_GAIN_DEFAULT", 0.5, REAL32),
        Spec("JS_GAIN_MAX", 1.0, REAL32),
        Spec("JS_GAIN_MIN", 0.25, REAL32),
        Spec("JS_GAIN_STEPS", 4, INT8),
        Spec("JS_THR_GAIN", 1.0, REAL32),
    ]
    # MANUAL_CONTROL's buttons (`sim_bridge.autopilot.buttons`): BTN0..15 by `Sub::default_js_buttons`, BTN16..31 none
    for n in range(BUTTONS):
        function, shifted = DEFAULTS[n] if n < len(DEFAULTS) else (0, 0)
        specs += [Spec(f"BTN{n}_FUNCTION", function, INT8), Spec(f"BTN{n}_SFUNCTION", shifted, INT8)]
    for ch in range(1, 17):
        specs += [Spec(f"RC{ch}_MIN", 1100, INT16), Spec(f"RC{ch}_MAX", 1900, INT16),
                  Spec(f"RC{ch}_TRIM", 1500, INT16), Spec(f"RC{ch}_DZ", 0, INT16)]   # DZ: RC_Channel's default
    # each motor of the frame on the output of its number (`AP_Motors::add_motor_num`), the other outputs unassigned
    motors = frame_of(frame).motors
    specs += [Spec(f"SERVO{n}_FUNCTION", MOTOR_FUNCTION_BASE + n if n <= motors else 0, INT16) for n in range(1, 17)]
    specs += [
        Spec("FS_GCS_ENABLE", 2, INT8),
        Spec("FS_GCS_TIMEOUT", 5.0, REAL32),
        Spec("FS_PILOT_INPUT", 2, INT8),
        Spec("FS_PILOT_TIMEOUT", 3.0, REAL32),
        Spec("BATT_CAPACITY", 18000, INT32),
        Spec("BARO1_GND_PRESS", 101325.0, REAL32),    # Pa calibrated at boot (AP_Baro): the surface, where the
        Spec("BARO2_GND_PRESS", 101325.0, REAL32),    # vehicle boots (`telemetry.SURFACE_PRESSURE`); 2: the Bar30
        Spec("BATT_ARM_VOLT", 0.0, REAL32),            # V below which arming is refused; 0: off
        Spec("BATT_ARM_MAH", 0, INT32),                # mAh left below which arming is refused; 0: off
        Spec("LOG_DISARMED", 0, INT8),                 # the on-board log (`onboard_log.logger`): 0 from arming
        Spec("LOG_FILE_DSRMROT", 0, INT8),             # 1: a new file after each disarm
        Spec("MIS_RESTART", 0, INT8),                  # AUTO resumes the mission (1: restarts it); AP_Mission
    ]
    specs += [Spec(*renamed(name, value, names.sysid == "MAV_SYSID"), REAL32)
              for name, value in GUIDED_DEFAULTS.items()]
    specs += _failsafe_table(names)
    for channel in range(CHANNELS):
        specs += [Spec(names.stream(channel, g), STREAM_DEFAULTS[g], INT16) for g in STREAM_GROUPS]
        if names.sysid == "MAV_SYSID":
            specs.append(Spec(f"{names.stream_prefix[channel]}OPTIONS", 0, INT16))
    specs += [
        Spec("SIM_SPEEDUP", 1.0, REAL32),
        Spec("SIM_BATT_VOLTAGE", 16.8, REAL32),
        Spec("SIM_BATT_CAP_AH", 18.0, REAL32),
    ]
    return specs


def _failsafe_table(names: Names) -> list[Spec]:
    """The leak, EKF, battery-monitor and SURFACE parameters (`sim_bridge.autopilot.failsafes`,
    `sim_bridge.modes.surface`), with
    Sub's defaults: ArduSub/Parameters.cpp and defines.h (FS_LEAK_ENABLE 1 warn only, FS_EKF_ACTION 0 disabled,
    FS_TERRAIN_ENAB 0 disarm, SURFACE_DEPTH -10 cm), AP_BattMonitor_Params.cpp (BATT_LOW_VOLT 0 outside Copter: no
    battery failsafe by default, BATT_LOW_TIMER 10 s), AC_WPNav's WPNAV_SPEED_UP (above) capped by PILOT_SPEED_UP."""
    specs = [
        Spec("FS_LEAK_ENABLE", 1, INT8),               # 0 off, 1 warn only, 2 SURFACE
        Spec("FS_EKF_ACTION", 0, INT8),                # 0 off, 1 warn only, 2 disarm
        Spec("FS_EKF_THRESH", 0.8, REAL32),
        Spec("BATT_LOW_TIMER", 10, INT8),              # s; 0: no voltage failsafe
        Spec("BATT_LOW_VOLT", 0.0, REAL32),            # V; 0: off
        Spec("BATT_LOW_MAH", 0.0, REAL32),
        Spec("BATT_CRT_VOLT", 0.0, REAL32),
        Spec("BATT_CRT_MAH", 0.0, REAL32),
        Spec("BATT_FS_LOW_ACT", 0, INT8),              # Sub: 0 none, 1 warn, 2 disarm, 3 SURFACE
        Spec("BATT_FS_CRT_ACT", 0, INT8),
        Spec("SURFACE_DEPTH", -10.0, REAL32),          # cm (negative: below the surface)
        Spec("FS_TERRAIN_ENAB", 0, INT8),              # AUTO's terrain failsafe: 0 disarm, 1 hold, 2 SURFACE
        Spec("PILOT_SPEED_UP", 500, INT16),            # cm/s (ArduSub/config.h PILOT_VELZ_MAX)
    ]
    specs += _rangefinder_table(names)
    if names.sysid == "MAV_SYSID":                     # 4.7 (PR #29996): SURFACE without a depth sensor
        specs.append(Spec("SFC_NOBARO_THST", 10, INT8))    # % throttle up, -100..100
    return specs


def _rangefinder_table(names: Names) -> list[Spec]:
    """The rangefinder and SURFTRAK (`sim_bridge.modes.terrain`): AP_RangeFinder_Params.cpp (RNGFND1_TYPE 0
    none, 10 MAVLink; RNGFND1_ORIENT 25, down; 4.7's RNGFND1_MIN/MAX in m, 0.2/7.0, were 4.5's RNGFND1_MIN_CM/MAX_CM,
    20/700), ArduSub/Parameters.cpp (RNGFND_SQ_MIN 90, SURFTRAK_DEPTH -50 cm, PILOT_SPEED_DN 0: PILOT_SPEED_UP's,
    PILOT_ACCEL_Z 100 cm/s/s)."""
    limits = ([Spec("RNGFND1_MIN", 0.2, REAL32), Spec("RNGFND1_MAX", 7.0, REAL32)] if names.sysid == "MAV_SYSID"
              else [Spec("RNGFND1_MIN_CM", 20, INT16), Spec("RNGFND1_MAX_CM", 700, INT16)])
    return [Spec("RNGFND1_TYPE", 0, INT8), Spec("RNGFND1_ORIENT", 25, INT8), *limits,
            Spec("RNGFND_SQ_MIN", 90, INT8), Spec("SURFTRAK_DEPTH", -50.0, REAL32),
            Spec("PILOT_SPEED_DN", 0, INT16), Spec("PILOT_ACCEL_Z", 100, INT16)]


def stored_value(value: float, ptype: int) -> float:
    """The value ArduPilot stores for a PARAM_SET of `value` (libraries/AP_Param/AP_Param.cpp, `set_float`): a
    float32; or, for an integer type, in float32 arithmetic, 0.01 added away from zero, clamped to the type's limits
    and truncated (documented ranges are not enforced). A finite value beyond float32 becomes infinite here, and
    `Params.set` refuses it."""
    value = f32(value)
    if ptype == REAL32 or not math.isfinite(value):
        return value
    low, high = _LIMITS[ptype]
    nudged = f32(value + (_ROUNDING if value >= 0 else -_ROUNDING))
    return float(float_to_int(f32(min(max(nudged, low), high))))


class Params:
    """The parameter table of one emulated vehicle, in ArduSub's send order (index = position)."""

    def __init__(self, firmware: str = DEFAULT_FIRMWARE, frame: int = BUILT_IN_FRAME):
        self.firmware = firmware
        self.names = names_for(firmware)
        self.specs = _table(self.names, frame)
        self._index = {s.name: i for i, s in enumerate(self.specs)}
        self._values = {s.name: float(s.default) for s in self.specs}
        self._stored = dict(self._values)
        self.version = 0                     # counts changes, for readers that cache derived values
        self._gains_version = -1

    def __len__(self) -> int:
        return len(self.specs)

    def __contains__(self, name: str) -> bool:
        return name in self._index

    def __getitem__(self, name: str) -> float:
        return self._values[name]

    def index(self, name: str) -> int:
        return self._index[name]

    def set(self, name: str, value: float, save: bool = True) -> float | None:
        """Apply a PARAM_SET as ArduSub does: the stored value, or None (nothing stored, no reply) for unknown names,
        NaN or infinity (libraries/GCS_MAVLink/GCS_Param.cpp, `handle_param_set`) and values beyond float32.
        `save=False` sets it in RAM only (lost at the next `reboot`)."""
        if name not in self._index or not math.isfinite(value):
            return None
        stored = stored_value(value, self.specs[self._index[name]].ptype)
        if not math.isfinite(stored):
            return None
        self._values[name] = stored
        if save:
            self._stored[name] = stored
        self.version += 1
        return stored

    def reboot(self) -> None:
        """Boot again: every value as stored (`AP_Param::load_all`)."""
        self._values = dict(self._stored)
        self.version += 1

    @property
    def gcs_sysid(self) -> int:
        return int(self._values[self.names.gcs_sysid])

    @property
    def sysid(self) -> int:
        return int(self._values[self.names.sysid])

    def is_gcs(self, sysid: int) -> bool:
        """`GCS::sysid_is_gcs`: the GCS sysid, or (4.7) any sysid up to MAV_GCS_SYSID_HI when that is above it."""
        low, high = self.gcs_sysid, int(self._values.get("MAV_GCS_SYSID_HI", 0))
        return low <= sysid <= high if high > low else sysid == low

    @property
    def gcs_only(self) -> bool:
        """MAV_OPTIONS bit 0 (4.5: SYSID_ENFORCE): MAVLink taken only from GCS sysids (`GCS_MAVLINK::accept_packet`)."""
        if "MAV_OPTIONS" in self._values:
            return bool(int(self._values["MAV_OPTIONS"]) & GCS_SYSID_ENFORCE)
        return bool(self._values.get("SYSID_ENFORCE", 0))

    def link_options(self, channel: int) -> int:
        """MAVn_OPTIONS of link `channel` (0 on 4.5, and on links past the last parameter set)."""
        if channel >= CHANNELS:
            return 0
        return int(self._values.get(f"{self.names.stream_prefix[channel]}OPTIONS", 0))

    def guided_gains(self) -> dict[str, float]:
        """GUIDED's controller parameters by their 4.5 names, in 4.5 units, whatever this firmware calls them."""
        if self._gains_version != self.version:
            self._gains = {}
            for name in GUIDED_DEFAULTS:
                new, scale = RENAMED_IN_4_7[name] if self.firmware == "4.7" and name in RENAMED_IN_4_7 else (name, 1)
                self._gains[name] = self._values[new] * scale
            self._gains_version = self.version
        return self._gains

    def stream_rate(self, channel: int, group: str) -> float:
        return self._values[self.names.stream(channel, group)]
