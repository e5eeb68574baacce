"""What the vehicle says about itself that ends a run (`flight.session.vehicle_events`), and a reboot seen on its
clock."""

from __future__ import annotations

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from rov_mav.flight.session.vehicle_clock import VehicleClock
from rov_mav.flight.session.vehicle_events import failsafe_text, position_lost


@pytest.mark.parametrize("text, name, stop", [
    ("Leak Detected", "leak", True),
    ("Battery 1 is critical 13.10V used 1523 mAh", "battery critical", True),
    ("Battery 1 is low 14.02V used 1200 mAh", "battery low", False),
    ("EKF bad", "estimator (EKF) failsafe", True),
    ("Depth sensor error!", "depth sensor lost", True),
])
def test_ardusubs_failsafe_texts_are_named(text, name, stop):
    fault = failsafe_text(text)
    assert fault is not None and fault.name == name and fault.stop is stop


@pytest.mark.parametrize("text", ["ArduPilot Ready", "Lost manual control", "MYGCS: 255, heartbeat lost",
                                  "Leak cleared? no", "Battery monitor ok"])
def test_other_texts_are_not_failsafes(text):
    assert failsafe_text(text) is None


def test_a_position_is_lost_without_either_horizontal_position_flag_or_in_constant_position_mode():
    good = (mavlink.EKF_ATTITUDE | mavlink.EKF_VELOCITY_HORIZ | mavlink.EKF_POS_HORIZ_REL | mavlink.EKF_POS_HORIZ_ABS
            | mavlink.EKF_POS_VERT_ABS)
    assert not position_lost(good)
    assert position_lost(good & ~(mavlink.EKF_POS_HORIZ_REL | mavlink.EKF_POS_HORIZ_ABS))
    assert position_lost(good | mavlink.EKF_CONST_POS_MODE)


def test_the_clock_going_back_is_a_reboot_but_a_late_sample_is_not():
    clock = VehicleClock(clock=lambda: 0.0)
    clock.observe(60.0, wall=1.0)
    clock.observe(59.7, wall=1.1)                  # reordered: kept out, not a reboot
    assert clock.reboots == [] and clock.last_vehicle == 60.0
    clock.observe(0.4, wall=5.0)                   # time_boot_ms restarted
    assert clock.reboots == [(60.0, 0.4)] and clock.last_vehicle == 0.4
