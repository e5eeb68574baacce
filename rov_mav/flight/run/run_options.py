"""What a run is asked to do (`RunOptions`, its `Limits`) and how it ends (`Abort` and its kinds, `RunResult`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rov_mav.flight.state.estimate_shaping import VELOCITY_BLEND
from rov_mav.mission.metrics import finite_percentile, loop_figures, pwm_activity

HANDED_OVER = 3                  # exit status: the pilot took the vehicle over
THRUSTERS, MOTOR_TEST = "thrusters", "motor-test"   # how the PWMs reach the outputs (`RunOptions.output`)
VEHICLE, MODEL = "vehicle", "model"                 # whose position estimate the law flies on (`RunOptions.estimator`)
DEFAULT_MAX_TILT_DEG = 15.0      # deg of roll or pitch: a BlueROV2 flies level; beyond this the law has lost it


@dataclass(frozen=True)
class Limits:
    max_depth: float | None = None            # m
    max_tracking_error: float | None = None   # m
    max_thrust: float | None = None           # N per thruster
    max_tilt: float | None = None             # rad, |roll| or |pitch|


@dataclass(frozen=True)
class RunOptions:
    rate: float = 50.0                 # Hz of vehicle time: telemetry and overrides
    dry_run: bool = False
    force: bool = False
    sysid: int | None = None           # our sysid; default: the vehicle's GCS sysid parameter
    heartbeat_timeout: float = 15.0    # wall s
    position_timeout: float = 90.0     # wall s to wait for LOCAL_POSITION_NED
    stale_periods: float = 3.0         # telemetry older than this many periods -> neutral
    link_timeout: float = 2.0          # vehicle s without telemetry -> abort
    approach_speed: float = 0.2        # m/s to the mission's start pose
    velocity_blend: float = VELOCITY_BLEND   # rad/s: the law's position and velocity blend (0: as reported)
    output: str = THRUSTERS            # THRUSTERS: RC overrides on RCIN passthrough; MOTOR_TEST: ArduSub's motor test
    predict: bool = True               # the law acts on the state predicted to when its command acts
    thruster_check: bool = True        # watch the thrusters for doing what they are told (`flight.run.thruster_watch`)
    estimator: str = VEHICLE           # VEHICLE: fly on the vehicle's estimate; MODEL: on our own (`own_navigation`)
    limits: Limits = Limits()

    @property
    def period(self) -> float:
        return 1.0 / self.rate


class Abort(Exception):
    """The run ends early for a stated reason; `code` is the process exit status."""

    def __init__(self, reason: str, code: int = 1):
        super().__init__(reason)
        self.reason = reason
        self.code = code


class LinkLost(Abort):
    pass


class HandOver(Abort):
    """Someone else is driving: hand the vehicle over to them (neutral, release, motors back), left armed."""

    def __init__(self, reason: str, t_detected: float, station=None):
        super().__init__(reason, HANDED_OVER)
        self.t_detected = t_detected
        self.station = station


class VehicleFailsafe(HandOver):
    """The vehicle's own failsafe acts (a leak, a critical battery, its estimator, its depth sensor, SURFACE): the
    run stops at once and leaves the vehicle to it, as to a pilot (not disarmed, its mode kept, motors back)."""

    def __init__(self, reason: str, t_detected: float, code: int):
        super().__init__(reason, t_detected)
        self.code = code


@dataclass
class RunResult:
    code: int
    reason: str
    completed: bool
    t: np.ndarray                      # (N,) mission ticks, vehicle s since the mission started
    eta: np.ndarray                    # (N, 6)
    eta_d: np.ndarray                  # (N, 6)
    truth: np.ndarray                  # (N, 3) true NED position where a simulator says it (SIM_STATE), else NaN
    reported: np.ndarray               # (N, 3) the vehicle's own position estimate (eta's, unless --estimator model)
    tau: np.ndarray                    # (N, 6)
    tau_hat: np.ndarray                # (N, 6)
    latency_ms: np.ndarray             # (M,) telemetry in -> command out (NaN for a tick between samples)
    tick_times: np.ndarray             # (M,) vehicle s of every tick
    horizon_ms: np.ndarray             # (M,) how far each tick's state was predicted (0: not predicted)
    pwm: np.ndarray                    # (M, 8) us each tick sent (GUIDED: the outputs the vehicle reported)
    round_trip_ms: float               # the link's round trip (TIMESYNC median) at the end, nan if never measured
    stalls: int                        # times this process stalled
    report: list[str] = field(default_factory=list)
    own_estimator: dict | None = None  # --estimator model: what its filter did (`OwnNavigation.figures`)
    heights: np.ndarray | None = None  # (N, 3) on altitude/standoff legs: the sounder's, the true, the leg's (else NaN)

    def loop_figures(self) -> dict:
        """The `loop` block (`mission.metrics.loop_figures`), with the prediction's horizon p50/p99 (ms), the round
        trip measured, the stalls of this process and the thrusters' activity (`mission.metrics.pwm_activity`)."""
        return {**loop_figures(self.tick_times, self.latency_ms),
                "horizon_p50_ms": finite_percentile(self.horizon_ms, 50),
                "horizon_p99_ms": finite_percentile(self.horizon_ms, 99),
                "round_trip_ms": self.round_trip_ms,
                "stalls": self.stalls,
                "pwm_activity_us_per_s": pwm_activity(self.tick_times, self.pwm)}
