"""A pilot's DataFlash dive as identification data (`offline.identify.dive_runs`): the motors found through the log's
SERVOn_FUNCTION and MOT_k_DIRECTION, the dive's own motion as its reference, and which DOFs it moved."""

from __future__ import annotations

import numpy as np
import pytest

from rov_mav.config import ConfigError
from rov_mav.model.dynamics import body_velocity
from rov_mav.model.frames import FRAMES
from rov_mav.offline.identify.dive_runs import excitation, motor_directions, motor_outputs, motor_pwm, own_reference

STANDARD, HEAVY = FRAMES[1], FRAMES[2]


def test_each_motor_is_found_at_the_output_its_function_names():
    params = {f"SERVO{n}_FUNCTION": 0.0 for n in range(1, 17)}
    params |= {"SERVO9_FUNCTION": 33.0, "SERVO2_FUNCTION": 34.0, "SERVO3_FUNCTION": 35.0, "SERVO4_FUNCTION": 36.0,
               "SERVO5_FUNCTION": 37.0, "SERVO1_FUNCTION": 38.0}
    outputs = motor_outputs(params, STANDARD)
    assert outputs == [9, 2, 3, 4, 5, 1]
    servo = np.arange(16.0)[None, :] + 1500.0
    np.testing.assert_array_equal(motor_pwm(servo, outputs), [[1508.0, 1501.0, 1502.0, 1503.0, 1504.0, 1500.0]])
    with pytest.raises(ConfigError, match="SERVO9, which the log does not record"):
        motor_pwm(servo[:, :8], outputs)
    with pytest.raises(ConfigError, match=r"motor 7 of FRAME_CONFIG 2 \(VECTORED_6DOF, 8 motors\) drives no output"):
        motor_outputs(params, HEAVY)
    assert motor_outputs({}, HEAVY) == list(range(1, 9))


def test_directions_are_the_logs_mot_k_direction():
    params = {"MOT_1_DIRECTION": -1.0, "MOT_2_DIRECTION": 1.0, "MOT_5_DIRECTION": -1.0}
    np.testing.assert_array_equal(motor_directions(params, 6), [-1, 1, 1, 1, -1, 1])


def test_the_own_reference_is_the_motion_and_its_derivatives_across_the_heading_wrap_and_a_gap():
    """A dive at 10 Hz with a gap: depth 0.5 sin(0.5 t), a steady turn of 0.6 rad/s wrapping at +-pi. Smoothed
    per stretch, the reference holds the depth, its rate and acceleration, and the turn rate with no wrap jumps."""
    t = np.concatenate([np.arange(0.0, 30.0, 0.1), np.arange(40.0, 70.0, 0.1)])
    eta = np.zeros((t.size, 6))
    eta[:, 2] = 0.5 * np.sin(0.5 * t)
    eta[:, 5] = (0.6 * t + np.pi) % (2 * np.pi) - np.pi
    ref = own_reference(t, eta)
    inside = np.ones(t.size, bool)
    for start in (0, 300):            # Savitzky-Golay edges are extrapolations: judge each stretch's inside
        inside[start:start + 10] = inside[start + 290:start + 300] = False
    np.testing.assert_allclose(ref[inside, 2], eta[inside, 2], atol=1e-3)
    np.testing.assert_allclose(ref[inside, 8], 0.25 * np.cos(0.5 * t[inside]), atol=2e-3)
    np.testing.assert_allclose(ref[inside, 14], -0.125 * np.sin(0.5 * t[inside]), atol=5e-3)
    np.testing.assert_allclose(ref[:, 11], 0.6, atol=1e-6)


def test_only_what_the_dive_moved_is_fitted_and_surge_and_sway_only_with_a_dvl():
    t = np.arange(0.0, 60.0, 0.1)
    still = own_reference(t, np.zeros((t.size, 6)))
    assert not any(e.fitted for e in excitation(still, horizontal_velocity=True))
    eta = np.zeros((t.size, 6))
    eta[:, 0] = 0.3 * np.sin(0.4 * t)                 # surging back and forth
    eta[:, 5] = 0.8 * np.sin(0.3 * t)                 # yawing
    moving = own_reference(t, eta)
    nu = body_velocity(moving[:, :6], moving[:, 6:12])
    without, with_dvl = excitation(moving, False), excitation(moving, True)
    assert [e.fitted for e in without] == [False, False, False, False, False, True]
    assert "no horizontal velocity" in without[0].why and "not excited" in without[2].why
    assert [e.fitted for e in with_dvl] == [True, False, False, False, False, True]
    assert with_dvl[5].motion == pytest.approx(np.std(nu[:, 5]))
