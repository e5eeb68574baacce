"""The bridge's MAV_CMD_DO_MOTOR_TEST as ArduSub 4.5 answers it (ArduSub/motors.cpp; measured on 4.5.3 SITL): on the
pure vehicle on a simulated clock, through the protocol layer, and once over UDP against the bridge in-process."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink
from bridge_helpers import BridgeThread, Gcs, mavutil

from sim_bridge.autopilot.ardusub import MAV_RESULT_ACCEPTED, MAV_RESULT_FAILED, MODES, ArduSub
from sim_bridge.gcs.missions import MissionProtocol
from sim_bridge.autopilot.params import Params
from sim_bridge.gcs.protocol import Protocol
from sim_bridge.gcs.schedule import Scheduler

PERCENT, PWM, PILOT = 0, 1, 2
BOARD = 2
T0 = 5.0                      # past ArduSub's first 2 s, in which no test starts
STEP = 0.0025
REFUSED_DISARMED = [(4, "Arm motors before testing motors."), (4, "motor test initialization failed!")]
COOLDOWN = [(2, "10 second cooldown required after motor test"), (4, "motor test initialization failed!")]
TIMED_OUT = [(6, "Motor test timed out!")]


def armed_vehicle(t: float = T0) -> ArduSub:
    """Armed in MANUAL at time t, without the failsafes (no pilot or GCS here)."""
    params = Params()
    params.set("FS_PILOT_INPUT", 0)
    params.set("FS_GCS_ENABLE", 0)
    sub = ArduSub(params)
    sub.update(t)
    sub.arm(True)
    return sub


def motor_test(sub: ArduSub, motor: float, pwm: float, t: float, throttle_type: float = PWM,
               test_type: int = BOARD) -> int:
    """One DO_MOTOR_TEST (PWM, board order unless told) at time t: its MAV_RESULT."""
    return sub.motor_test(motor, throttle_type, pwm, test_type, t)


def motors(sub: ArduSub) -> list[int]:
    return [int(v) for v in sub.servo_outputs()[:8]]


def run(sub: ArduSub, t0: float, t1: float) -> float:
    """Main-loop passes after t0 up to t1 at 400 Hz; returns t1."""
    for k in range(int(round((t1 - t0) / STEP))):
        sub.update(t0 + (k + 1) * STEP)
    return t1


# -- the vehicle -----------------------------------------------------------------------------------------------


def test_refused_when_disarmed_then_no_new_start_for_2_s():
    sub = armed_vehicle()
    sub.arm(False)
    assert motor_test(sub, 0, 1600, T0) == MAV_RESULT_FAILED and not sub.motor_testing
    assert sub.texts == REFUSED_DISARMED
    sub.texts.clear()
    sub.arm(True)
    assert motor_test(sub, 0, 1600, T0 + 2.0) == MAV_RESULT_FAILED and sub.texts == []     # silently, for 2 s
    assert motor_test(sub, 0, 1600, T0 + 2.01) == MAV_RESULT_ACCEPTED and sub.motor_testing
    assert motors(sub)[0] == 1600


def test_nothing_starts_in_the_first_2_s_after_boot():
    sub = armed_vehicle(t=0.0)
    assert motor_test(sub, 0, 1600, 1.0) == motor_test(sub, 0, 1600, 2.0) == MAV_RESULT_FAILED and sub.texts == []
    assert motor_test(sub, 0, 1600, 2.01) == MAV_RESULT_ACCEPTED


def test_zero_based_index_and_raw_pwm_without_motor_directions_or_limits():
    sub = armed_vehicle()
    sub.params.set("MOT_1_DIRECTION", -1)
    assert motor_test(sub, 0, 1600, T0) == MAV_RESULT_ACCEPTED
    assert motors(sub) == [1600] + [1500] * 7                     # not reversed; untouched motors neutral
    assert motor_test(sub, 7, 2100, T0) == MAV_RESULT_ACCEPTED           # param1 7 drives SERVO8; past MOT_PWM_MAX
    assert motor_test(sub, 1.9, 1000.7, T0) == MAV_RESULT_ACCEPTED       # truncated: SERVO2, 1000
    assert motors(sub) == [1600, 1000, 1500, 1500, 1500, 1500, 1500, 2100]
    assert motor_test(sub, 8, 1700, T0) == MAV_RESULT_FAILED and sub.texts == []
    assert motors(sub) == [1600, 1000, 1500, 1500, 1500, 1500, 1500, 2100]
    # out-of-range casts as on ARM: motor uint8_t (256 -> 0), PWM int16_t then rc_write's uint16_t
    assert motor_test(sub, 256, -1, T0) == motor_test(sub, 2, 70000, T0) == MAV_RESULT_ACCEPTED
    assert motors(sub)[:3] == [65535, 1000, 4464]


def test_motor_outputs_follow_their_servo_function():
    sub = armed_vehicle()
    sub.params.set("SERVO9_FUNCTION", 34)                          # motor 2 also on SERVO9
    sub.params.set("SERVO2_FUNCTION", 0)
    assert motor_test(sub, 1, 1650, T0) == MAV_RESULT_ACCEPTED
    out = sub.servo_outputs()
    assert out[1] == 0 and out[8] == 1650


def test_pilot_input_and_assisted_modes_do_not_reach_the_motors_during_a_test():
    sub = armed_vehicle()
    sub.rc_override(255, [1500, 1500, 1800, 1600, 1900, 1500, 1500, 1500] + [0] * 10, T0)
    sub.update(T0)
    assert motors(sub) != [1500] * 8
    assert motor_test(sub, 4, 1550, T0) == MAV_RESULT_ACCEPTED
    assert motors(sub) == [1500] * 4 + [1550] + [1500] * 3
    assert sub.set_mode(MODES["ALT_HOLD"])
    state = (np.array([0, 0, 5.0, 0.3, 0.2, 0]), np.zeros(6))    # tilted: the holds would push back
    for k in range(1, 40):
        sub.update(T0 + k * STEP, state)
        if k % 20 == 0:
            motor_test(sub, 4, 1550, T0 + k * STEP)
    assert motors(sub) == [1500] * 4 + [1550] + [1500] * 3
    assert sub.rc.radio_in[4] == 1900 and sub.armed                 # RC input still read


def test_timeout_after_half_a_second_disarms_and_neutralises():
    sub = armed_vehicle()
    assert motor_test(sub, 0, 1700, T0) == MAV_RESULT_ACCEPTED
    run(sub, T0, T0 + 0.5)
    assert sub.motor_testing and sub.armed and motors(sub)[0] == 1700 and sub.texts == []
    sub.update(T0 + 0.5 + STEP)
    assert sub.texts == TIMED_OUT and not sub.motor_testing and not sub.armed
    assert motors(sub) == [1500] * 8
    sub.arm(True)
    assert motors(sub)[0] == 1500                                   # the mixer again


def test_commands_at_350_hz_keep_it_running():
    sub = armed_vehicle()
    t = T0
    for k in range(700):                                           # 2 s
        t = T0 + k / 350
        assert motor_test(sub, 3, 1580, t) == MAV_RESULT_ACCEPTED
        sub.update(t)
    assert sub.motor_testing and sub.armed and sub.texts == [] and motors(sub)[3] == 1580
    run(sub, t, t + 0.6)
    assert sub.texts == TIMED_OUT and not sub.armed


def test_10_s_cooldown_after_a_timeout_and_2_s_between_failed_starts():
    sub = armed_vehicle()
    motor_test(sub, 3, 1700, T0)
    run(sub, T0, T0 + 0.6)
    ended = T0 + 0.5 + STEP
    sub.texts.clear()
    sub.arm(True)
    assert motor_test(sub, 0, 1600, ended + 1.0) == MAV_RESULT_FAILED and sub.texts == COOLDOWN
    sub.texts.clear()
    assert motor_test(sub, 0, 1600, ended + 3.0) == MAV_RESULT_FAILED and sub.texts == []   # 2 s after a failure
    assert motor_test(sub, 0, 1600, ended + 9.0) == MAV_RESULT_FAILED and sub.texts == COOLDOWN
    sub.texts.clear()
    assert motor_test(sub, 0, 1600, ended + 10.5) == MAV_RESULT_FAILED and sub.texts == []    # cooldown over, 2 s not
    assert motor_test(sub, 0, 1600, ended + 11.01) == MAV_RESULT_ACCEPTED
    assert motors(sub) == [1600] + [1500] * 7                      # a new test starts from neutral


def test_a_disarm_does_not_end_the_test_nor_free_the_thrusters_the_timeout_does_and_starts_the_cooldown():
    """Sub::motors_output calls only verify_motor_test while a test runs: a disarm writes nothing, so the last test
    PWM stays on the thruster; a refused command still stamps the test alive (handle_do_motor_test stamps first)."""
    sub = armed_vehicle()
    assert motor_test(sub, 0, 1600, T0) == MAV_RESULT_ACCEPTED
    assert motor_test(sub, 3, 1900, T0) == MAV_RESULT_ACCEPTED
    sub.arm(False)
    assert motors(sub) == [1600, 1500, 1500, 1900] + [1500] * 4 and sub.motor_testing
    t = run(sub, T0, T0 + 0.4)
    assert motor_test(sub, 0, 1500, t) == MAV_RESULT_FAILED and sub.texts == []   # output_test_num: not armed
    run(sub, t, t + 0.5)
    assert sub.motor_testing and sub.texts == []                  # the refused command kept it alive ...
    assert motors(sub) == [1600, 1500, 1500, 1900] + [1500] * 4   # ... with the last accepted PWMs on
    sub.update(t + 0.5 + STEP)
    assert sub.texts == TIMED_OUT and not sub.motor_testing
    assert motors(sub) == [1500] * 8                              # the timeout frees them
    sub.texts.clear()
    sub.arm(True)
    assert motor_test(sub, 0, 1600, t + 3.0) == MAV_RESULT_FAILED and sub.texts == COOLDOWN


def test_percent_throttle_maps_onto_rc3_range():
    sub = armed_vehicle()
    expected = {0: 1100, 30: 1340, 50: 1500, 99.99: 1899, 100: 1900, 150: 1900, -5: 1100, math.nan: 1500}
    for percent, pwm in expected.items():
        assert motor_test(sub, 2, percent, T0, throttle_type=PERCENT) == MAV_RESULT_ACCEPTED
        assert motors(sub)[2] == pwm, percent
    sub.params.set("RC3_MIN", 1000)
    sub.params.set("MOT_PWM_MIN", 1300)                           # not used by the test
    assert motor_test(sub, 2, 25, T0, throttle_type=PERCENT) == MAV_RESULT_ACCEPTED and motors(sub)[2] == 1225


def test_bad_test_and_throttle_types_are_refused_after_the_test_started():
    sub = armed_vehicle()
    assert motor_test(sub, 0, 1600, T0, test_type=0) == MAV_RESULT_FAILED
    assert sub.texts == [(4, "bad test type 0.00")] and sub.motor_testing and motors(sub) == [1500] * 8
    sub.texts.clear()
    assert motor_test(sub, 0, 1600, T0, test_type=-1) == MAV_RESULT_FAILED             # uint32_t
    assert motor_test(sub, 0, 1600, T0, throttle_type=PILOT) == MAV_RESULT_FAILED
    assert motor_test(sub, 0, 1600, T0, throttle_type=3) == MAV_RESULT_FAILED           # no text
    assert sub.texts == [(4, "bad test type 4294967295.00"), (4, "bad throttle type 2.00")]
    assert motors(sub) == [1500] * 8


# -- the protocol layer ----------------------------------------------------------------------------------------


def protocol_for(sub: ArduSub) -> tuple[Protocol, Scheduler]:
    scheduler = Scheduler(("HEARTBEAT",), lambda g: 0)
    return Protocol(sub, sub.params, snapshot=lambda: None, on_params_changed=lambda t: None,
                    missions=MissionProtocol(lambda: (0.0, 0.0, 0.0))), scheduler


def ack(proto: Protocol, scheduler: Scheduler, msg, sender: int, t: float):
    """The COMMAND_ACK to `msg` packed by system `sender` (any sysid, not only the GCS's)."""
    peer = mavlink.MAVLink(None, srcSystem=sender, srcComponent=190)
    [(reply, to_all)] = proto.handle(mavlink.MAVLink(None).decode(bytearray(msg.pack(peer))), 0, scheduler, t)
    assert reply.get_type() == "COMMAND_ACK" and reply.command == 209 and reply.target_system == sender
    assert not to_all
    return reply.result


def test_command_long_and_int_from_any_sysid():
    sub = armed_vehicle()
    sub.arm(False)
    proto, scheduler = protocol_for(sub)

    def command_long(*params, sender=42, t=T0):
        return ack(proto, scheduler, mavlink.MAVLink_command_long_message(1, 1, 209, 0, *params), sender, t)

    assert command_long(0, PWM, 1600, 0, 0, BOARD, 0) == MAV_RESULT_FAILED and sub.texts == REFUSED_DISARMED
    sub.arm(True)
    assert command_long(1, PWM, 1600, 0, 0, 2.9, 0, t=T0 + 3) == MAV_RESULT_ACCEPTED    # param6 truncated to y = 2
    assert motors(sub)[1] == 1600
    sub.texts.clear()
    assert command_long(1, PWM, 1600, 0, 0, 1.9, 0, t=T0 + 3) == MAV_RESULT_FAILED
    assert sub.texts == [(4, "bad test type 1.00")]
    command_int = mavlink.MAVLink_command_int_message(1, 1, 0, 209, 0, 0, 5, PWM, 1700, 0, 0, BOARD, 0)
    assert ack(proto, scheduler, command_int, 7, T0 + 3) == MAV_RESULT_ACCEPTED and motors(sub)[5] == 1700


# -- over MAVLink ----------------------------------------------------------------------------------------------

SPEEDUP = 2.0
mav = mavutil.mavlink


@pytest.mark.process
def test_motor_test_over_udp_runs_times_out_disarms_and_cools_down():
    with BridgeThread(SPEEDUP) as running:
        gcs = Gcs(running.port, SPEEDUP, rate=5.0)
        try:
            gcs.connect()
            gcs.override = [1500] * 8
            gcs.start_pump()
            assert gcs.command(mav.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == mav.MAV_RESULT_ACCEPTED
            while gcs.sim_time_now() <= 2.0:                       # no test starts in ArduSub's first 2 s
                pass
            received = []
            deadline = time.monotonic() + 1.5                     # 3 s simulated, a command every 0.05 s wall
            while time.monotonic() < deadline:
                gcs.send("command_long", 1, 1, mav.MAV_CMD_DO_MOTOR_TEST, 0, 1, PWM, 1650, 0, 0, BOARD, 0)
                received += gcs.collect(0.05, ["COMMAND_ACK", "SERVO_OUTPUT_RAW"])
            acks = [m.result for m in received if m.get_type() == "COMMAND_ACK"]
            servos = [m for m in received if m.get_type() == "SERVO_OUTPUT_RAW"]
            assert len(acks) > 10 and set(acks) == {mav.MAV_RESULT_ACCEPTED}
            assert [getattr(servos[-1], f"servo{i}_raw") for i in range(1, 9)] == [1500, 1650] + [1500] * 6
            assert gcs.recv("STATUSTEXT", cond=lambda m: m.text == "Motor test timed out!").severity == 6
            assert gcs.recv("HEARTBEAT", cond=lambda m: not m.base_mode & 128)
            servo = gcs.recv("SERVO_OUTPUT_RAW")
            assert [getattr(servo, f"servo{i}_raw") for i in range(1, 9)] == [1500] * 8
            assert gcs.command(mav.MAV_CMD_DO_MOTOR_TEST, 1, PWM, 1650, 0, 0, BOARD).result == \
                mav.MAV_RESULT_FAILED
            assert gcs.recv("STATUSTEXT", cond=lambda m: "cooldown" in m.text).severity == 2
        finally:
            gcs.close()
