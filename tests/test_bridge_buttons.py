"""MANUAL_CONTROL's buttons on the built-in vehicle as ArduSub acts on them (ArduSub/joystick.cpp, Sub's default
button functions; `sim_bridge.autopilot.buttons`), and the arming check that a button must be able to disarm
(`AP_Arming_Sub::has_disarm_function`)."""

from __future__ import annotations

from sim_bridge.autopilot.ardusub import MAV_RESULT_ACCEPTED, MAV_RESULT_FAILED, MODES, ArduSub
from sim_bridge.autopilot.params import Params

AT_REST = (0, 0, 500, 0, 0, 0)          # x, y, z, r, s, t: sticks centred


def vehicle() -> ArduSub:
    params = Params()
    params.set("FS_PILOT_INPUT", 0)
    params.set("FS_GCS_ENABLE", 0)
    sub = ArduSub(params)
    sub.update(1.0)
    return sub


def buttons(sub: ArduSub, *pressed: int, sysid: int = 255, t: float = 1.0) -> bool:
    return sub.manual_control(sysid, 1, AT_REST, t, sum(1 << b for b in pressed))


def test_the_default_buttons_arm_disarm_and_change_modes():
    sub = vehicle()
    buttons(sub, 6)
    assert sub.armed                                          # button 6: arm (with the checks)
    buttons(sub, 2)
    assert sub.mode == MODES["ALT_HOLD"]
    buttons(sub, 3)
    assert sub.mode == MODES["STABILIZE"]
    buttons(sub, 1)
    assert sub.mode == MODES["MANUAL"]
    buttons(sub, 4)
    assert not sub.armed                                      # button 4: disarm
    buttons(sub, 6, sysid=200)                                # not a GCS sysid: nothing
    assert not sub.armed


def test_shift_gives_each_button_its_shift_function():
    sub = vehicle()
    sub.params.set("BTN10_SFUNCTION", 3)                      # shift + 10: arm (10 alone: mount tilt up, nothing)
    buttons(sub, 10)
    assert not sub.armed
    buttons(sub, 5, 10)
    assert sub.armed


def test_arm_toggle_acts_on_every_message_while_held():
    sub = vehicle()
    sub.params.set("BTN0_FUNCTION", 2)
    states = []
    for k in range(4):
        buttons(sub, 0, t=1.0 + 0.04 * k)
        states.append(sub.armed)
    assert states == [True, False, True, False]


def test_buttons_16_to_31_come_in_buttons2():
    sub = vehicle()
    sub.params.set("BTN17_FUNCTION", 3)
    sub.manual_control(255, 1, AT_REST, 1.0, 1 << 17)
    assert sub.armed


def test_a_vehicle_no_button_can_disarm_refuses_to_arm_unless_forced():
    sub = vehicle()
    sub.params.set("BTN4_FUNCTION", 0)
    assert sub.arm(True) == MAV_RESULT_FAILED
    assert sub.texts == [(2, "Arm: Must assign a disarm or arm_toggle button or disarm aux function")]
    sub.params.set("BTN11_SFUNCTION", 4)                      # shift (button 5) + 11 disarms: enough
    assert sub.arm(True) == MAV_RESULT_ACCEPTED
    sub.arm(False)
    sub.params.set("BTN11_SFUNCTION", 0)
    assert sub.arm(True, checks=False) == MAV_RESULT_ACCEPTED and sub.armed
