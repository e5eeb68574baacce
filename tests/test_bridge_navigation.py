"""Navigation in the built-in vehicle: the presets, the sensors drawn from the truth, the EKF3 stand-in (lag, drift,
steps, consistency), the sources' own messages and the truth on the link, the command line.

The estimator's behaviour is measured on the sensors and estimator alone along a known path (fast, exact); the
bridge's messages on bridges stepped by hand with a recording link, and once over UDP with pymavlink."""

from __future__ import annotations

import math
import subprocess
import time
from dataclasses import replace

import numpy as np
import pytest
from bridge_helpers import ROV_MAV, BridgeThread, Gcs

from rov_mav.config import ConfigError
from rov_mav.model.environment import load_environment
from rov_mav.model.navigation import PRESETS, Dvl, Ugps, load_navigation
from sim_bridge.navigation import aiding as ekf_status
from sim_bridge.config import BridgeConfig
from sim_bridge.navigation.estimator import RETRY_NO_VEL, TAU_OUTPUT, Estimator
from sim_bridge.navigation.sensors import ImuSample, Sensors, UgpsFix
from sim_bridge.server import Bridge
from sim_bridge.navigation.source_messages import DVL_SOURCE, UGPS_SOURCE
from sim_bridge.gcs.telemetry import EARTH_RADIUS

STEP = 0.0025
QUIET = {"FS_PILOT_INPUT": 0, "FS_GCS_ENABLE": 0}


# -- the sensors and the estimator along a known path ----------------------------------------------------------


def straight(speed: float, weave: float = 0.0):
    """North at `speed` m/s at 5 m depth, heading north, with an optional sideways weave (m)."""
    def truth(t):
        eta = np.array([speed * t, weave * math.sin(0.2 * t), 5.0, 0.0, 0.0, 0.0])
        nu = np.array([speed, weave * 0.2 * math.cos(0.2 * t), 0.0, 0.0, 0.0, 0.0])
        return eta, nu
    return truth


def fly(nav, truth, seconds: float, seed: int = 1, every: float = 0.1):
    """(times, estimate - truth in N, E, D, the estimator) sampled every `every` s."""
    eta, nu = truth(0.0)
    sensors, est = Sensors(nav, seed, eta, nu), Estimator(nav, 0.0, eta, nu)
    times, errors = [], []
    stride = round(every / STEP)
    for k in range(round(seconds / STEP)):
        t = k * STEP
        eta, nu = truth(t)
        for item in sensors.sample(t, eta, nu):
            est.feed(item)
        if k % stride == 0:
            times.append(t)
            errors.append(est.output[0][:3] - eta[:3])
    return np.array(times), np.array(errors), est


def clean_ugps(**changes) -> Ugps:
    return replace(Ugps(outlier_probability=0.0, dropout_probability=0.0), **changes)


@pytest.mark.parametrize("ekf_delay", [0.0, 0.2])
def test_ugps_estimate_lags_the_truth_by_the_latency_the_ekf_does_not_know_of(ekf_delay):
    nav = replace(PRESETS["ugps"], ugps=clean_ugps(ekf_delay=ekf_delay))
    speed = 0.4
    times, errors, _ = fly(nav, straight(speed), 90.0)
    settled = errors[times > 20]
    lag = -settled[:, 0].mean() / speed                           # s behind along the track
    assert lag == pytest.approx(nav.ugps.latency - ekf_delay, abs=0.06)
    across = np.sqrt(np.mean(settled[:, 1] ** 2))
    assert 0.01 < across < 0.3                                     # noisy, bounded


def test_a_late_fix_after_a_dropout_moves_the_estimate_from_when_it_arrives_over_the_output_time_constant():
    """EKF3's output predictor (`calcOutputStates`): the fix is fused at the horizon when it arrives, and what the
    vehicle reports follows the filter over about EK3_TAU_OUTPUT (0.25 s), not in one step."""
    nav = replace(PRESETS["ugps"], ugps=clean_ugps(ekf_delay=0.2))
    eta, nu = np.array([0, 0, 5.0, 0, 0, 0]), np.zeros(6)
    est = Estimator(nav, 0.0, eta, nu)
    dt = 0.02
    outputs = []
    for k in range(1, 501):                                         # 10 s, no fix, a 0.02 m/s^2 accelerometer bias
        t = k * dt
        if k == 400:                                                # the late fix (truth: still at the origin)
            est.feed(UgpsFix(t - 0.4, t, 0.0, 0.0, 0.1, True))
        est.feed(ImuSample(t, dt, np.array([0.02 * dt, 0, 0]), np.zeros(3), 0.0, 0.0))
        outputs.append(est.output[0][0])
    steps = np.diff(outputs)
    correction = outputs[398]
    assert correction > 0.5                                         # drifted on the IMU alone: 0.5 a t^2 ~ 0.6 m
    assert np.all(steps[:398] >= 0) and steps[398] < 0              # back from the sample it arrived with
    assert np.abs(steps).max() < 0.1 * correction                   # spread, not a step
    assert outputs[398 + int(round(2 * TAU_OUTPUT / dt))] < 0.3 * correction    # mostly taken in within 2 tau


def test_a_fix_after_the_retry_time_without_one_that_fails_its_gate_resets_the_position_at_once():
    """No fix passed for the retry time (7 s without the DVL) and the next one fails the innovation gate: EKF3 resets
    its position to it (`FuseVelPosNED`, `ResetPosition`), the report moves at once, and a reset is counted."""
    nav = replace(PRESETS["ugps"], ugps=clean_ugps(ekf_delay=0.2))
    est = Estimator(nav, 0.0, np.array([0, 0, 5.0, 0, 0, 0]), np.zeros(6))
    dt = 0.02
    outputs = []
    for k in range(1, 501):
        t = k * dt
        if k == 400:                                                # 8 s in: a fix 30 m away, far outside the gate
            est.feed(UgpsFix(t - 0.4, t, 30.0, 0.0, 0.1, True))
        est.feed(ImuSample(t, dt, np.zeros(3), np.zeros(3), 0.0, 0.0))
        outputs.append(est.output[0][0])
    assert est.resets == 1 and est.retry == RETRY_NO_VEL
    assert outputs[398] == pytest.approx(0.0, abs=1e-6) and outputs[399] == pytest.approx(30.0, abs=1e-6)


def test_dvl_dead_reckoning_drifts_with_the_distance_travelled():
    nav = replace(PRESETS["dvl"], dvl=Dvl(lock_loss_rate=0.0))
    times, errors, _ = fly(nav, straight(0.5), 200.0)
    horizontal = np.hypot(errors[:, 0], errors[:, 1])
    at_10m, at_100m = horizontal[np.searchsorted(times, 20.0)], horizontal[-1]
    assert at_100m > 4 * at_10m
    # mostly the compass's 2 degree bias turning the track: about 100 m x 0.035 sideways
    assert at_100m == pytest.approx(100 * nav.compass.bias, rel=0.35)
    assert abs(errors[-1, 1]) > abs(errors[-1, 0])


def test_the_filters_innovations_are_consistent():
    nav = replace(PRESETS["dvl+ugps"], ugps=clean_ugps(), dvl=Dvl(lock_loss_rate=0.0, scale_error=0.0))
    _, _, est = fly(nav, straight(0.3, weave=2.0), 150.0, seed=4)
    for kind in ("pos", "vel", "hgt", "mag"):
        values = [nis / dim for k, nis, dim in est.nis if k == kind]
        assert len(values) > 300, kind
        assert 0.6 < np.mean(values) < 1.5, (kind, np.mean(values))


def test_outliers_are_gated_and_glitching_shows():
    nav = replace(PRESETS["ugps"], ugps=clean_ugps(outlier_probability=0.2, outlier_size=5.0))
    _, errors, est = fly(nav, straight(0.2), 60.0, seed=2)
    assert est.ratios["pos"] >= 0.0
    rejected = sum(1 for k, nis, dim in est.nis if k == "pos" and nis / (25 * dim) > 1)
    assert rejected == 0                                            # nothing past the gate was fused
    assert np.sqrt(np.mean(errors[100:, 0] ** 2)) < 0.4


def test_the_sensors_are_reproducible_from_the_seed():
    def draws(seed):
        s = Sensors(PRESETS["dvl+ugps"], seed, *straight(0.3)(0.0))
        out = []
        for k in range(4000):
            out += [repr(x) for x in s.sample(k * STEP, *straight(0.3)(k * STEP))]
        return out
    assert draws(5) == draws(5)
    assert draws(5) != draws(6)


# -- bridges stepped by hand -------------------------------------------------------------------------------------


class Recorder:
    """A link that keeps what is sent, with the sender's (sysid, compid)."""

    channel = 0

    def __init__(self, bridge: Bridge):
        self.bridge, self.sent = bridge, []

    def send(self, msg) -> None:
        self.sent.append((round(self.bridge.t, 4), msg, (self.bridge.sub.sysid, 1)))

    def send_as(self, msg, source) -> None:
        self.sent.append((round(self.bridge.t, 4), msg, source))

    def deliver(self): pass

    def receive(self): return []

    def sockets(self): return []

    def restart(self, sysid): pass

    def drop_clients(self): pass

    def close(self): pass

    def of(self, kind: str):
        return [(t, m, src) for t, m, src in self.sent if m.get_type() == kind]


def stepped(navigation: str | None, seconds: float, **config) -> tuple[Bridge, Recorder]:
    nav = PRESETS[navigation] if isinstance(navigation, str) else navigation
    b = Bridge(BridgeConfig(endpoints=(), navigation=nav, start_depth=3.0, params=QUIET, **config))
    link = Recorder(b)
    b.links = [link]
    b._start_streams()
    for _ in range(round(seconds / b.physics.h)):
        b._step()
    return b, link


def test_none_sends_attitude_and_depth_but_never_a_local_position_nor_position_flags():
    b, link = stepped("none", 12.0)
    assert not link.of("LOCAL_POSITION_NED")
    assert link.of("ATTITUDE") and link.of("SCALED_PRESSURE2") and link.of("GLOBAL_POSITION_INT")
    flags = {m.flags for _, m, _ in link.of("EKF_STATUS_REPORT")}
    position = ekf_status.POS_HORIZ_ABS | ekf_status.POS_HORIZ_REL | ekf_status.PRED_POS_HORIZ_ABS
    assert flags == {ekf_status.CONST_POS_FLAGS} and not ekf_status.CONST_POS_FLAGS & position
    assert not link.of("GPS_INPUT") and not link.of("VISION_POSITION_DELTA")
    assert not b.sub.set_mode(16)                                  # POSHOLD needs a position
    assert abs(b.estimate[0][2] - b.physics.plant.eta[2]) < 0.02   # depth from the Bar30


def test_ideal_is_the_old_telemetry_exactly(tmp_path):
    old_types = {"HEARTBEAT", "ATTITUDE", "LOCAL_POSITION_NED", "GLOBAL_POSITION_INT", "SCALED_PRESSURE2", "VFR_HUD",
                 "SERVO_OUTPUT_RAW", "RC_CHANNELS", "SYS_STATUS", "BATTERY_STATUS", "EKF_STATUS_REPORT",
                 "SYSTEM_TIME", "MISSION_CURRENT", "NAMED_VALUE_FLOAT"}    # RFTarget, as ArduSub sends it
    (tmp_path / "env.yaml").write_text("environment:\n  noise: {position: 0.05, attitude: 0.01}\n")
    environment = load_environment(tmp_path / "env.yaml")
    a, link_a = stepped(None, 5.0, environment=environment, seed=3)
    b, link_b = stepped("ideal", 5.0, environment=environment, seed=3)
    assert {m.get_type() for _, m, _ in link_a.sent} == old_types
    def content(link):      # SYSTEM_TIME's Unix time follows the host's clock
        return [(t, {k: v for k, v in m.to_dict().items() if k != "time_unix_usec"}) for t, m, _ in link.sent]
    assert content(link_a) == content(link_b)
    x = np.array([m.x for _, m, _ in link_b.of("LOCAL_POSITION_NED")])
    assert 0.03 < x.std() < 0.07                                   # the environment's noise, as before


def test_ugps_fixes_and_dvl_deltas_go_out_at_their_rates_from_their_own_ids():
    b, link = stepped("dvl+ugps", 30.0, seed=1)
    gps = link.of("GPS_INPUT")
    assert {src for _, _, src in gps} == {UGPS_SOURCE} == {(1, 220)}
    assert len(gps) / 30.0 == pytest.approx(3.8, abs=0.1)
    fixes = [m for _, m, _ in gps if m.fix_type == 3]
    assert len(fixes) > 0.8 * len(gps) and all(m.ignore_flags == 1 | 8 | 16 | 32 | 128 for _, m, _ in gps)
    assert all(m.horiz_accuracy == 300 and m.hdop == 65535 for _, m, _ in gps if m.fix_type == 0)
    deltas = link.of("VISION_POSITION_DELTA")
    assert {src for _, _, src in deltas} == {DVL_SOURCE} == {(255, 0)}
    assert 0.8 * 5.0 <= len(deltas) / 30.0 <= 5.0 + 0.1           # a few lost to bottom-lock losses
    intervals = np.array([m.time_delta_usec for _, m, _ in deltas])
    assert np.median(intervals) == pytest.approx(200_000, abs=1) and intervals.min() >= 200_000 - 2_501
    own = [src for _, m, src in link.sent if m.get_type() in ("HEARTBEAT", "ATTITUDE", "SIM_STATE",
                                                              "LOCAL_POSITION_NED")]
    assert set(own) == {(1, 1)}                                    # the autopilot's own stay 1/1


def test_sim_state_is_the_truth_and_the_estimate_differs_from_it_a_little():
    b, link = stepped("ugps", 20.0, seed=2)
    lat0, lon0, alt0 = b.config.origin
    sim = link.of("SIM_STATE")
    assert len(sim) / 20.0 == pytest.approx(10.0, abs=0.2)          # EXTRA1's default rate, as ATTITUDE
    _, last, _ = sim[-1]
    eta = b.physics.plant.eta
    north = math.radians(last.lat_int / 1e7 - lat0) * EARTH_RADIUS
    assert north == pytest.approx(eta[0], abs=0.02)
    assert last.alt == pytest.approx(alt0 - eta[2], abs=0.01)
    assert last.lat == pytest.approx(last.lat_int, abs=1.0)         # degE7 in the float too, as SITL
    assert not link.of("GPS_GLOBAL_ORIGIN")                        # nobody heard on the link yet
    errors = []
    sim_times = np.array([t for t, _, _ in sim])
    for t, m, _ in link.of("LOCAL_POSITION_NED"):
        nearest = int(np.argmin(np.abs(sim_times - t)))
        if abs(sim_times[nearest] - t) < 0.06 and t > 2.0:
            s = sim[nearest][1]
            tn = math.radians(s.lat_int / 1e7 - lat0) * EARTH_RADIUS
            te = math.radians(s.lon_int / 1e7 - lon0) * EARTH_RADIUS * math.cos(math.radians(lat0))
            errors.append(math.hypot(m.x - tn, m.y - te))
    assert len(errors) > 20
    assert 0.005 < np.sqrt(np.mean(np.square(errors))) < 0.5


def test_the_navigation_lost_fault_still_works_on_an_aided_vehicle():
    from rov_mav.model.vehicle_faults import parse_vehicle_faults
    b, link = stepped("ugps", 25.0, vehicle_faults=parse_vehicle_faults(["navigation-lost@2s"]))
    flags = [(t, m.flags) for t, m, _ in link.of("EKF_STATUS_REPORT")]
    assert flags[0][1] & ekf_status.POS_HORIZ_ABS
    assert flags[-1][1] == ekf_status.CONST_POS_FLAGS
    dropped = min(t for t, f in flags if not f & ekf_status.POS_HORIZ_ABS)
    assert 2.0 + 7.0 <= dropped <= 2.0 + 1.0 + 7.0 + 0.4            # the source lost, then EKF3's 7 s
    assert all(m.fix_type == 0 for t, m, _ in link.of("GPS_INPUT") if t > 2.5)
    assert max(t for t, _, _ in link.of("LOCAL_POSITION_NED")) < 2.0 + 1.0 + 15.0 + 0.4


# -- over UDP, the environment file and the command line -------------------------------------------------------


@pytest.mark.process
def test_a_ground_station_sees_the_sources_and_the_truth_from_their_ids():
    with BridgeThread(navigation=PRESETS["dvl+ugps"], params=QUIET) as bridge:
        gcs = Gcs(bridge.port, speedup=bridge.speedup)
        seen: dict[str, set] = {}
        gcs.conn.mav.heartbeat_send(6, 8, 0, 0, 0)
        deadline, origin = time.monotonic() + 10, None
        while time.monotonic() < deadline and (len(seen) < 4 or origin is None):
            msg = gcs.conn.recv_match(type=["GPS_INPUT", "VISION_POSITION_DELTA", "SIM_STATE", "HEARTBEAT",
                                            "GPS_GLOBAL_ORIGIN"], blocking=True, timeout=1)
            if msg is not None and msg.get_type() == "GPS_GLOBAL_ORIGIN":
                origin = msg
            elif msg is not None:
                seen.setdefault(msg.get_type(), set()).add((msg.get_srcSystem(), msg.get_srcComponent()))
        gcs.conn.close()
    assert seen == {"GPS_INPUT": {(1, 220)}, "VISION_POSITION_DELTA": {(255, 0)}, "SIM_STATE": {(1, 1)},
                    "HEARTBEAT": {(1, 1)}}
    assert origin is not None and origin.latitude == round(bridge.bridge.config.origin[0] * 1e7)


def test_an_environment_file_carries_the_navigation(tmp_path):
    path = tmp_path / "env.yaml"
    path.write_text("environment:\n  navigation:\n    preset: ugps\n    ugps: {rate: 2.0, latency: 0.6}\n")
    nav = load_environment(path).navigation
    assert nav.ugps.rate == 2.0 and nav.ugps.latency == 0.6 and nav.dvl is None
    path.write_text("environment:\n  navigation: dvl\n")
    assert load_environment(path).navigation == PRESETS["dvl"]
    path.write_text("environment:\n  navigation: {preset: ugps, ugps: {rate: 0}}\n")
    with pytest.raises(ConfigError, match=r"navigation: .*rate: Input should be greater than 0$"):
        load_environment(path)
    path.write_text("navigation:\n  preset: dvl\n  dvl: {noise: 0.02}\n")
    assert load_navigation(str(path)).dvl.noise == 0.02


@pytest.mark.parametrize("arg, expected", [
    ("bogus", "navigation: unknown preset 'bogus' (one of ideal, none, dvl, ugps, dvl+ugps, or a YAML file)"),
    ("BAD_FILE", "outlier_probability: Input should be less than or equal to 1"),
])
@pytest.mark.process
def test_the_command_line_refuses_a_bad_navigation_in_one_line(tmp_path, arg, expected):
    if arg == "BAD_FILE":
        arg = str(tmp_path / "nav.yaml")
        (tmp_path / "nav.yaml").write_text("navigation:\n  preset: ugps\n  ugps: {outlier_probability: 2}\n")
    result = subprocess.run([ROV_MAV, "sim-bridge", "--navigation", arg], capture_output=True, text=True,
                            timeout=60)
    assert result.returncode == 2
    lines = [line for line in result.stderr.splitlines() if "error:" in line]
    assert len(lines) == 1 and lines[0].endswith(expected), result.stderr
