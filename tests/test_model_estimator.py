"""The run's own model-aided estimator (`flight.state.model_estimator`) against a simulated vehicle: the shared compiled
plant under a known wrench, a body disturbance and a current, acoustic fixes that are noisy and 0.4 s late, the
Bar30's depth. What it must do: beat the fixes it is given by a wide margin, learn the force and the current the
model does not know, fuse a late fix at its own time, refuse an outlier, take in a lasting jump after RESET_AFTER at
a flyable pace, and give the law an output that moves less than its raw estimate and never strays from it."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from rov_mav.flight.state import model_estimator as me
from rov_mav.model import kernel
from rov_mav.model.environment import Environment
from rov_mav.model.vehicle import load_vehicle

FIX_NOISE = 0.15          # m
DISTURBANCE = np.array([-1.0, 1.0, 2.0, 0.1, 0.1, 0.0])
CURRENT = np.array([0.04, 0.03, 0.0])


def _wrench(t: float) -> np.ndarray:
    return np.array([20 * np.sin(0.2 * t), 15 * np.cos(0.13 * t), 5 * np.sin(0.3 * t), 0, 0, 3 * np.sin(0.1 * t)])


def _fly(duration: float = 60.0, latency: float = me.UGPS_LATENCY, fix_offset=lambda t: np.zeros(2),
         outlier_at: float | None = None, seed: int = 1, disturbance: np.ndarray = DISTURBANCE):
    """Simulate and estimate; returns (estimator, times, errors (n, 6): raw position and output position - truth,
    outputs (n, 3), raw (n, 3), gaps (n,): m from the output to the filter's position less what it holds back)."""
    vehicle = load_vehicle()
    m = vehicle.packed()
    env = Environment(disturbance=disturbance, current=CURRENT).packed(vehicle)
    rng = np.random.default_rng(seed)
    x = np.zeros(12)
    x[2] = 2.0
    ws = np.zeros(80)
    est = me.ModelEstimator(m)
    est.start(0.0, x[:6], x[6:])
    h, sample = 0.002, 0.02
    fixes, next_fix, times, errors, outputs, raws, gaps = [], 0.0, [], [], [], [], []
    for k in range(int(duration / h)):
        t = k * h
        tau = _wrench(t)
        if k % round(sample / h) == 0:
            est.commanded(t, tau)
        kernel.rk4_step(m, env, x, tau, t, h, ws)
        t = (k + 1) * h
        if t >= next_fix - 1e-9:
            next_fix += 1 / 3.8
            error = FIX_NOISE * rng.standard_normal(2) + fix_offset(t)
            if outlier_at is not None and abs(t - outlier_at) < 0.13:
                error = error + np.array([3.0, -3.0])
            fixes.append((t + latency, *(x[:2] + error)))
        if (k + 1) % round(sample / h) == 0:
            est.advance(t, np.concatenate([x[3:6], x[9:12]]))
            est.depth(t, x[2] + 0.005 * rng.standard_normal())
            while fixes and fixes[0][0] <= t + 1e-9:
                arrival, north, east = fixes.pop(0)
                est.fix(arrival, north, east, FIX_NOISE)
            times.append(t)
            errors.append(np.r_[est.z[:3] - x[:3], est.position - x[:3]])
            gaps.append(float(np.linalg.norm(est.position - (est.z[:3] - est.held))))
            outputs.append(est.position)
            raws.append(est.z[:3].copy())
    return est, np.array(times), np.array(errors), np.array(outputs), np.array(raws), np.array(gaps)


def _rms(e: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum(e ** 2, axis=1))))


@pytest.fixture(scope="module")
def flown():
    return _fly()


def test_it_beats_the_fixes_it_is_given_and_learns_what_the_model_does_not_know(flown):
    est, t, errors, _, _, _ = flown
    settled = t > 20.0
    horizontal = _rms(errors[settled, :2])
    assert horizontal < 0.5 * FIX_NOISE * np.sqrt(2), horizontal      # the fixes' own RMS is 0.21 m
    assert _rms(errors[settled, 3:5]) < 0.6 * FIX_NOISE * np.sqrt(2)  # the output too, smoothed
    assert np.sqrt(np.mean(errors[settled, 2] ** 2)) < 0.01            # depth from the Bar30
    np.testing.assert_allclose(est.z[6:9], DISTURBANCE[:3], atol=0.6)  # the body force the model lacks
    np.testing.assert_allclose(est.z[9:11], CURRENT[:2], atol=0.02)    # and the current
    assert est.refused["fix"] == 0 and est.fused["fix"] > 200


def test_a_late_fix_is_fused_at_its_own_time(monkeypatch):
    """Fixes 1 s late, fused at their time of validity, against the same fixes fused as if they had just been taken:
    the latter estimate is worse."""
    monkeypatch.setattr(me, "UGPS_LATENCY", 1.0)
    _, t, errors, _, _, _ = _fly(latency=1.0)
    monkeypatch.setattr(me, "UGPS_LATENCY", 0.0)
    _, _, naive, _, _, _ = _fly(latency=1.0)
    settled = t > 20.0
    assert _rms(errors[settled, :2]) < 0.7 * _rms(naive[settled, :2])


def test_an_outlier_is_refused(flown):
    _, t, errors, _, _, _ = flown
    est, t_out, with_outlier, _, _, _ = _fly(outlier_at=30.0)
    assert est.refused["fix"] >= 1
    after = (t_out > 30.0) & (t_out < 35.0)
    assert np.max(np.linalg.norm(with_outlier[after, :2], axis=1)) < 0.3


def test_a_lasting_jump_is_taken_in_after_reset_after_at_a_flyable_pace():
    """From t = 30 s every fix is 2 m further north (a topside transceiver moved, a reset): refused at first,
    then taken, and the output moves to it at CATCH_UP m/s at most."""
    est, t, errors, outputs, raws, _ = _fly(duration=60.0, fix_offset=lambda t: np.array([2.0, 0.0]) * (t >= 30.0))
    assert est.refused["fix"] > 5
    late = t > 55.0
    assert np.all(np.abs(errors[late, 0] - 2.0) < 0.4), "the estimate followed the fixes in the end"
    jumped = t > 30.0
    steps = np.linalg.norm(np.diff(outputs[jumped], axis=0), axis=1) / np.diff(t[jumped])
    truth_speed = 1.0     # m/s: more than the simulated vehicle's own speed
    assert np.max(steps) < truth_speed + me.CATCH_UP
    raw_steps = np.linalg.norm(np.diff(raws[jumped], axis=0), axis=1)
    assert np.max(raw_steps) > 1.0       # the filter itself jumped: the output is what kept the pace


def test_the_law_sees_an_output_that_moves_less_than_the_raw_estimate(flown):
    _, t, _, outputs, raws, _ = flown
    settled = t > 20.0

    def variation(a):
        return float(np.sum(np.abs(np.diff(np.diff(a[settled], axis=0), axis=0))))   # of the velocity it implies

    assert variation(outputs) < 0.5 * variation(raws)


def test_the_output_stays_with_the_filter_while_it_learns_a_current_it_did_not_know(monkeypatch):
    """A 0.36 m/s current the filter starts without: until it is learnt, every fix pushes the filter's velocity the
    same way and the model pulls it back between fixes. The output follows the filter's position and velocity (less
    the jumps it holds back), so it stays within a few fixes' corrections of it (when its whole correction was
    clamped at CATCH_UP, it strayed 1.03 m here), and is as near the truth as the filter once the current is learnt."""
    monkeypatch.setattr(sys.modules[__name__], "CURRENT", np.array([0.3, -0.2, 0.0]))
    _, t, errors, _, _, gaps = _fly(duration=60.0)
    assert np.max(gaps) < 0.5, np.max(gaps)
    settled = t > 30.0
    assert _rms(errors[settled, 3:5]) < 1.2 * _rms(errors[settled, :2]) + 0.01


def _still(est: me.ModelEstimator, start: float, end: float, fix_std: float = 0.1, seed: int = 2) -> list[float]:
    """A vehicle holding still at the origin, 2 m down, told nothing: the vehicle's own estimate and depth every
    0.02 s, a fix every 1/3.8 s; returns the filter's horizontal distance from the truth at each step."""
    rng = np.random.default_rng(seed)
    attitude, distances, next_fix = np.zeros(6), [], start
    for t in np.arange(start + 0.02, end, 0.02):
        est.advance(t, attitude)
        est.depth(t, 2.0)
        est.vehicle(t, 0.0, 0.0, np.zeros(3))
        if t >= next_fix:
            next_fix += 1 / 3.8
            est.fix(t, *(fix_std * rng.standard_normal(2)), fix_std)
        distances.append(float(np.linalg.norm(est.z[:2])))
    return distances


def test_a_filter_gone_wrong_is_reset_to_the_fix_and_the_vehicles_velocity_and_stays_right():
    """The filter, sure of itself, believes it is 3 m north and moving on at 0.6 m/s against a 100 N force of its own
    making. Its fixes are refused; after RESET_AFTER s it resets its position to the
    fix, its velocity to the vehicle's and learns the force afresh, and from then on it holds (a reset of the position
    alone left the wrong velocity and force to carry it away again)."""
    est = me.ModelEstimator(load_vehicle().packed())
    est.start(0.0, np.array([0, 0, 2.0, 0, 0, 0]), np.zeros(6))
    _still(est, 0.0, 10.0)                       # settled on its fixes
    for z in [est.z] + [step.z for step in est.steps]:     # its whole kept history
        z[0], z[3], z[6] = z[0] + 3.0, 0.6, -100.0
    resets = est.resets
    distances = _still(est, 10.0, 40.0)
    assert est.resets == resets + 1 and est.refused["fix"] > 5
    assert max(distances[-int(15 / 0.02):]) < 0.3           # its last 15 s: right, and no second reset
    assert abs(est.z[6]) < 5.0


def test_a_measurement_valid_after_the_filters_time_is_held_until_the_filter_gets_there():
    """A fix read before the state samples of its own time (a loaded ground computer reads its link late) is neither
    dropped nor fused early: held, then fused once the filter reaches its time."""
    est = me.ModelEstimator(load_vehicle().packed())
    est.start(0.0, np.array([0, 0, 2.0, 0, 0, 0]), np.zeros(6))
    est.advance(1.0, np.zeros(6))
    assert not est.fix(1.0 + me.UGPS_LATENCY + 0.3, 0.0, 0.0, 0.1)      # valid at 1.3 s
    assert est.ahead["fix"] == 1 and est.fused["fix"] == 0
    est.advance(1.2, np.zeros(6))
    assert est.fused["fix"] == 0
    est.advance(1.4, np.zeros(6))
    assert est.fused["fix"] == 1
