"""The built-in vehicle follows FRAME_CONFIG as ArduSub does (libraries/AP_Motors/AP_Motors6DOF.cpp `setup_motors`
and its three mixer paths; `AP_Motors::add_motor_num` for the outputs; `GCS_MAVLINK_Sub::send_banner`): the motors
the frame has, each mixed as ArduSub mixes it, on the outputs of their numbers, the frame read at boot only."""

from __future__ import annotations

import numpy as np
import pytest

from rov_mav.model.frames import FRAMES, HEAVY, frame_of
from sim_bridge.autopilot import mixer
from sim_bridge.autopilot.ardusub import ArduSub
from sim_bridge.autopilot.params import Params
from sim_bridge.hardware.physics import Harness
from sim_bridge.gcs.telemetry import banner

T0 = 5.0
FRAME_STRINGS = {0: "BLUEROV1", 1: "VECTORED", 2: "VECTORED_6DOF", 3: "VECTORED_6DOF_90DEG", 4: "SIMPLEROV_3",
                 5: "DEFAULT", 6: "DEFAULT", 7: "SIMPLEROV_3"}
MOTOR_COUNTS = {0: 6, 1: 6, 2: 8, 3: 8, 4: 3, 5: 5, 6: 5, 7: 3}


def vehicle(frame: int) -> ArduSub:
    """A vehicle booted with FRAME_CONFIG `frame`, armed in MANUAL, without the failsafes."""
    params = Params(frame=frame)
    params.set("FS_PILOT_INPUT", 0)
    params.set("FS_GCS_ENABLE", 0)
    sub = ArduSub(params)
    sub.update(T0)
    sub.arm(True, checks=False)
    return sub


def stick(sub: ArduSub, **channels: int) -> list[int]:
    """Hold RC overrides (ch1 pitch, ch2 roll, ch3 throttle, ch4 yaw, ch5 forward, ch6 lateral); SERVO1..16."""
    values = [1500] * 8 + [0] * 10
    for name, value in channels.items():
        values[int(name[2:]) - 1] = value
    sub.rc_override(255, values, T0)
    sub.update(T0 + 0.01)
    return [int(v) for v in sub.servo_outputs()]


@pytest.mark.parametrize("config", range(8))
def test_each_frame_has_ardusubs_motors_outputs_and_banner(config):
    sub = vehicle(config)
    n = MOTOR_COUNTS[config]
    assert sub.frame.motors == n and banner("4.7", sub.frame)[1] == f"Frame: {FRAME_STRINGS[config]}"
    functions = [int(sub.params[f"SERVO{k}_FUNCTION"]) for k in range(1, 17)]
    assert functions == [32 + k for k in range(1, n + 1)] + [0] * (16 - n)      # motor k on SERVOk, the rest none
    out = stick(sub)
    assert out[:n] == [1500] * n and out[n:] == [0] * (16 - n)                   # unassigned outputs: no pulse
    assert sub.motor_test(n - 1, 1, 1600, 2, T0 + 3) == 0 and sub.servo_outputs()[n - 1] == 1600
    assert sub.motor_test(n, 1, 1600, 2, T0 + 3) == 4                            # no such motor: FAILED


def test_an_unknown_frame_config_takes_the_default_five_motor_table():
    assert frame_of(42).motors == 5 and frame_of(42).name == "DEFAULT"


def test_the_frame_is_read_at_boot_only():
    """FRAME_CONFIG is @RebootRequired: a PARAM_SET changes the stored value, the mixer only after a reboot."""
    params = Params()
    sub = ArduSub(params)
    params.set("FRAME_CONFIG", 1)
    assert sub.frame is HEAVY
    params.reboot()
    assert ArduSub(params).frame is FRAMES[1]


def test_vectored_limits_forward_on_the_thrusters_that_push_that_way_by_the_throttle():
    """AP_Motors6DOF::output_armed_stabilizing_vectored: forward 0.5 with throttle 0.8 (MOT_FV_CPLNG_K 1: limit
    0.2) on motors 3-4 (forward side +); motors 1-2 keep the full -0.5; motors 5-6 take the throttle."""
    out = mixer.mix([0, 0, 0, 0.8, 0.5, 0], np.ones(6), FRAMES[1])
    assert out == pytest.approx([-0.5, -0.5, 0.2, 0.2, -0.8, -0.8])
    out = mixer.mix([0, 0, 0, 0.8, -0.5, 0], np.ones(6), FRAMES[1])           # reverse: motors 1-2 limited
    assert out == pytest.approx([0.2, 0.2, -0.5, -0.5, -0.8, -0.8])
    assert mixer.mix([0, 0, 0, 0.8, 0.5, 0], np.ones(6), FRAMES[1], coupling=0.0)[2] == pytest.approx(0.5)


def test_only_vectored_6dof_scales_its_groups_the_others_clip():
    """Roll 1 with throttle 1 on the vertical thrusters (roll +-1, throttle -1): sums (0, -2, 0, -2) on the Heavy,
    which VECTORED_6DOF scales by 2 as a group; VECTORED clips them one by one; within 1 nothing is scaled."""
    grouped = mixer.mix([1, 0, 0, 1, 0, 0], np.ones(8), HEAVY)               # motors 5-8: roll +-1, throttle -1
    assert grouped[4:] == pytest.approx([0.0, -1.0, 0.0, -1.0])              # (0, -2, 0, -2) / 2
    summed = mixer.mix([1, 0, 0, 1, 0, 0], np.ones(6), FRAMES[1])             # motors 5-6: the same factors
    assert summed[4:] == pytest.approx([0.0, -1.0])                          # (0, -2) clipped
    assert mixer.mix([0.5, 0, 0, 0.5, 0, 0], np.ones(8), HEAVY)[5] == pytest.approx(-1.0)   # within 1: not scaled
    ninety = mixer.mix([1, 0, 0, 1, 0, 0], np.ones(8), FRAMES[3])
    assert ninety[0] == 1.0 and ninety[7] == 0.0                             # 1 + 1 clipped; -1 + 1


def test_motor_directions_reverse_the_whole_sum_before_the_clip():
    assert mixer.mix([0, 0, 0, 0.4, 0.3, 0], [-1, 1, 1, 1, 1, 1], FRAMES[1])[0] == pytest.approx(0.3)


def test_a_standard_bluerov2_drives_only_its_six_thrusters():
    """FRAME_CONFIG 1 on the bridge: throttle up moves motors 5 and 6 only; outputs 7 and 8 send no pulse, and the
    hull's thrusters 7 and 8, which no output was set up to drive, get none."""
    sub = vehicle(1)
    out = stick(sub, ch3=1700)
    assert out[:4] == [1500] * 4 and out[4] == out[5] < 1500 and out[6:8] == [0, 0]
    harness = Harness([int(sub.params[f"SERVO{k}_FUNCTION"]) for k in range(1, 17)], 8)
    assert list(harness.wires) == [0, 1, 2, 3, 4, 5, -1, -1]
    assert list(harness.pwm(np.array(out))) == out[:6] + [0, 0]


def test_the_harness_follows_where_the_motors_were_set_up():
    outputs = np.arange(16) + 1000
    assert list(Harness([0] * 8 + list(range(33, 41)), 8).pwm(outputs)) == list(range(1008, 1016))
    assert list(Harness(list(range(33, 41)) + [0] * 8, 8).pwm(outputs)) == list(range(1000, 1008))
