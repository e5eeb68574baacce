"""How the vehicle knows where it is: the navigation presets and every parameter of their sensors.

A `Navigation` names which horizontal source aids the autopilot's estimator (none, a DVL, an acoustic positioning
system, both) and how each sensor errs. The built-in vehicle draws its sensors from the plant's true state with these
figures and fuses them in its EKF stand-in (`sim_bridge.navigation.sensors`, `sim_bridge.navigation.estimator`);
`ideal` keeps the old
behaviour (the plant's state plus the environment's noise, valid from boot).

Default figures and where they come from (chosen where no source gives one, and said so):
- DVL (Water Linked DVL A50 class). Velocity reports at 5 Hz: the A50's rate depends on its altitude, "in the range
  2-15 Hz" (Water Linked DVL protocol documentation, velocity report); 5 Hz is chosen for a few metres of altitude.
  Noise 0.01 m/s per axis per report and a 0.5 % scale error (chosen: within the A50 datasheet's long-term accuracy
  of +-1.01 %, as recalled, not re-read here; the documentation's example report at 0.5 m altitude has a figure of
  merit of 0.0002 m/s). Latency 0.2 s: the documentation's example report leaves the DVL 0.19 s after its time of
  validity, plus the BlueOS extension's hop through mavlink2rest. Bottom lock lost 0.01 times a second for 2 s on
  average (chosen: soft or steep ground).
- Acoustic positioning (Water Linked Underwater GPS G2 class). Fixes at 3.8 Hz (the GPS_INPUT rate of a real
  BlueROV2 Heavy log, issue 20; the BlueOS UGPS extension polls the topside every 0.25 s, `app/main.py`). Noise
  0.1 m + 1 % of the slant range from a topside transceiver at the origin (the G2's accuracy is given as about 1 % of
  range, as recalled from its datasheet; the 0.1 m floor is chosen). Latency 0.4 s (chosen: acoustic flight, topside
  processing, the 0.25 s polling, HTTP). Outliers 1 % of fixes, 3 m (chosen); a dropout starts at 1 % of fixes and
  lasts 3 s on average (chosen).
- What the EKF assumes of each source's delay: 0.2 s for the GPS (AP_GPS_Backend's default lag, unverified for the
  MAVLink backend) and 0.01 s for visual odometry (VISO_DELAY_MS's default), so a late fix is fused at the wrong
  time and the estimate lags by the difference.
- IMU at 50 Hz (the estimator's prediction rate; ArduPilot's EKF3 predicts at up to 400 Hz): 0.02 m/s^2 and
  0.001 rad/s of noise per sample (chosen above an ICM-20602's 100 ug/rtHz and 0.004 deg/s/rtHz, for thruster
  vibration), a 0.002 rad/s gyro bias the heading filter estimates; tilt 0.2 deg (chosen).
- Compass at 10 Hz, 1 deg of noise and a 2 deg bias (chosen: a calibrated compass near thrusters and a battery).
- Bar30 (MS5837-30BA) at 20 Hz, 0.005 m of noise (its 0.2 mbar resolution is 2 mm of water; chosen above it).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Annotated, Any

from pydantic import Field

from rov_mav import config

PRESET_NAMES = ("ideal", "none", "dvl", "ugps", "dvl+ugps")

Positive = Annotated[float, Field(gt=0)]
NonNegative = Annotated[float, Field(ge=0)]
Probability = Annotated[float, Field(ge=0, le=1)]
Rate = Annotated[float, Field(gt=0, le=400)]
Delay = Annotated[float, Field(ge=0, le=5)]


class NavigationError(ValueError):
    """A navigation preset or file is invalid; the message is one line."""


@dataclass(frozen=True)
class Imu:
    rate: float = 50.0                 # Hz: the estimator's prediction rate
    accel_noise: float = 0.02          # m/s^2 per sample
    gyro_noise: float = 0.001          # rad/s per sample
    gyro_bias: float = 0.002           # rad/s about the vertical (estimated by the heading filter)
    tilt_error: float = 0.0035         # rad: the AHRS's roll and pitch error (slowly varying)
    accel_process: float = 0.1         # m/s^2: the filter's process noise (what it does not model)


@dataclass(frozen=True)
class Compass:
    rate: float = 10.0                 # Hz
    noise: float = 0.0175              # rad
    bias: float = 0.035                # rad: a heading error the filter cannot see


@dataclass(frozen=True)
class Bar30:
    rate: float = 20.0                 # Hz
    noise: float = 0.005               # m


@dataclass(frozen=True)
class Dvl:
    rate: float = 5.0                  # Hz of velocity reports
    noise: float = 0.01                # m/s per axis per report
    scale_error: float = 0.005         # fraction of the velocity
    bias: float = 0.0                  # m/s on each body axis
    latency: float = 0.2               # s from the ping to the autopilot
    ekf_delay: float = 0.01            # s the EKF assumes (VISO_DELAY_MS)
    lock_loss_rate: float = 0.01       # bottom-lock losses per second
    lock_loss_duration: float = 2.0    # s, mean


@dataclass(frozen=True)
class Ugps:
    rate: float = 3.8                  # Hz of fixes
    noise: float = 0.1                 # m, at the transceiver
    noise_per_range: float = 0.01      # m of noise per m of slant range
    transceiver: tuple[float, float, float] = (0.0, 0.0, 0.0)   # NED m: the topside transceiver
    latency: float = 0.4               # s from the fix to the autopilot
    ekf_delay: float = 0.2             # s the EKF assumes (the GPS lag)
    outlier_probability: float = 0.01
    outlier_size: float = 3.0          # m, standard deviation of an outlier's error
    dropout_probability: float = 0.01  # a dropout starts at a fix
    dropout_duration: float = 3.0      # s, mean
    noise_floor: float = 0.0           # m: the least noise the EKF assumes (EK3_POSNE_M_NSE-like)


@dataclass(frozen=True)
class Navigation:
    """A preset or a file's navigation: which sources, and how every sensor errs. `dvl` / `ugps` None: absent."""

    name: str = "ideal"
    dvl: Dvl | None = None
    ugps: Ugps | None = None
    imu: Imu = field(default_factory=Imu)
    compass: Compass = field(default_factory=Compass)
    bar30: Bar30 = field(default_factory=Bar30)
    # the built-in vehicle's further sensors, by section, as written (each sensor's own module reads its section and
    # refuses what it does not know: `sim_bridge.navigation.attached`); any preset, ideal too, may carry them
    more: dict[str, Any] = field(default_factory=dict, hash=False)

    @property
    def ideal(self) -> bool:
        return self.name == "ideal"

    @property
    def has_position_source(self) -> bool:
        return self.dvl is not None or self.ugps is not None

    def describe(self) -> str:
        if self.ideal:
            return "ideal"
        sources = "+".join(s for s, on in (("dvl", self.dvl), ("ugps", self.ugps)) if on) or "none"
        return sources if self.name in PRESET_NAMES else f"{self.name} ({sources})"


PRESETS = {
    "ideal": Navigation("ideal"),
    "none": Navigation("none"),
    "dvl": Navigation("dvl", dvl=Dvl()),
    "ugps": Navigation("ugps", ugps=Ugps()),
    "dvl+ugps": Navigation("dvl+ugps", dvl=Dvl(), ugps=Ugps()),
}


# -- the file schema -------------------------------------------------------------------------------------------


class ImuSchema(config.StrictModel):
    rate: Rate = Imu.rate
    accel_noise: NonNegative = Imu.accel_noise
    gyro_noise: NonNegative = Imu.gyro_noise
    gyro_bias: float = Imu.gyro_bias
    tilt_error: NonNegative = Imu.tilt_error
    accel_process: Positive = Imu.accel_process


class CompassSchema(config.StrictModel):
    rate: Rate = Compass.rate
    noise: Positive = Compass.noise
    bias: float = Compass.bias


class Bar30Schema(config.StrictModel):
    rate: Rate = Bar30.rate
    noise: Positive = Bar30.noise


class DvlSchema(config.StrictModel):
    rate: Rate = Dvl.rate
    noise: Positive = Dvl.noise
    scale_error: float = Dvl.scale_error
    bias: float = Dvl.bias
    latency: Delay = Dvl.latency
    ekf_delay: Delay = Dvl.ekf_delay
    lock_loss_rate: NonNegative = Dvl.lock_loss_rate
    lock_loss_duration: Positive = Dvl.lock_loss_duration


class UgpsSchema(config.StrictModel):
    rate: Rate = Ugps.rate
    noise: Positive = Ugps.noise
    noise_per_range: NonNegative = Ugps.noise_per_range
    transceiver: Annotated[list[float], Field(min_length=3, max_length=3)] = list(Ugps.transceiver)
    latency: Delay = Ugps.latency
    ekf_delay: Delay = Ugps.ekf_delay
    outlier_probability: Probability = Ugps.outlier_probability
    outlier_size: NonNegative = Ugps.outlier_size
    dropout_probability: Probability = Ugps.dropout_probability
    dropout_duration: Positive = Ugps.dropout_duration
    noise_floor: NonNegative = Ugps.noise_floor


class NavigationSchema(config.StrictModel):
    """A `navigation:` block: a preset to start from (default none), then any sensor's parameters. A `dvl:` or
    `ugps:` section adds that source to the preset's; another section is one of the built-in vehicle's further
    sensors (`Navigation.more`), read by that sensor."""

    model_config = config.StrictModel.model_config | {"extra": "allow"}

    preset: str = "none"
    imu: ImuSchema | None = None
    compass: CompassSchema | None = None
    bar30: Bar30Schema | None = None
    dvl: DvlSchema | None = None
    ugps: UgpsSchema | None = None


def _dataclass_of(kind, schema) -> Any:
    values = schema.model_dump()
    if "transceiver" in values:
        values["transceiver"] = tuple(float(v) for v in values["transceiver"])
    return kind(**values)


def from_schema(s: NavigationSchema, name: str) -> Navigation:
    base = preset(s.preset)
    if base.ideal and any(getattr(s, k) is not None for k in ("imu", "compass", "bar30", "dvl", "ugps")):
        raise NavigationError("navigation: preset ideal takes no sensor parameters (it has no sensors)")
    updates = {kind: _dataclass_of(cls, getattr(s, kind)) for kind, cls in
               (("imu", Imu), ("compass", Compass), ("bar30", Bar30), ("dvl", Dvl), ("ugps", Ugps))
               if getattr(s, kind) is not None}
    more = dict(s.model_extra or {})
    return replace(base, name=name if updates else base.name, more=more, **updates)


def preset(name: str) -> Navigation:
    try:
        return PRESETS[name]
    except KeyError:
        raise NavigationError(f"navigation: unknown preset '{name}' (one of {', '.join(PRESET_NAMES)}, or a "
                              "YAML file)") from None


def parse_navigation(value, source: str = "navigation") -> Navigation:
    """A preset name or a `navigation:` mapping (NavigationError, one line, naming `source`)."""
    if isinstance(value, str):
        return preset(value.strip())
    if not isinstance(value, dict):
        raise NavigationError(f"{source}: expected a preset name ({', '.join(PRESET_NAMES)}) or a mapping")
    try:
        block = config.parse(NavigationSchema, value, source)
    except config.ConfigError as exc:
        raise NavigationError(str(exc)) from None
    return from_schema(block, Path(source).stem if source != "navigation" else "custom")


def load_navigation(arg: str) -> Navigation:
    """The option's value: a preset name, or a YAML file holding a `navigation:` block (or that block's keys)."""
    if arg.strip() in PRESETS:
        return PRESETS[arg.strip()]
    path = Path(arg)
    if not path.exists() and "/" not in arg and not arg.endswith((".yaml", ".yml")):
        raise NavigationError(f"navigation: unknown preset '{arg}' (one of {', '.join(PRESET_NAMES)}, or a YAML "
                              "file)")
    try:
        data = config.read_yaml(path)
    except config.ConfigError as exc:
        raise NavigationError(str(exc)) from None
    block = data.get("navigation", data) if isinstance(data, dict) else data
    if isinstance(block, dict) and "environment" in block and "navigation" not in block:
        block = (block["environment"] or {}).get("navigation")
        if block is None:
            raise NavigationError(f"{path}: navigation: missing")
    try:
        return parse_navigation(block, str(path))
    except NavigationError as exc:
        message = str(exc)
        raise NavigationError(message if message.startswith(str(path)) else f"{path}: {message}") from None
