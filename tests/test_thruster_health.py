"""The runner's thruster watch: the estimate (`flight.thrusters.thruster_health`) on a closed loop of the real law,
allocation
and plant with a thruster failing inside the plant, and the allocation around a thruster (`Actuation.set_gain`)."""

from __future__ import annotations

import numpy as np
import pytest

from rov_mav.control.controller import Controller, load_settings
from rov_mav.flight.thrusters.actuation import Actuation
from rov_mav.flight.thrusters.thruster_health import EVIDENCE, SETTLE, ThrusterHealth
from rov_mav.mission.loader import load
from rov_mav.model.environment import Environment
from rov_mav.model.plant import Plant
from rov_mav.model.vehicle import load_vehicle
from rov_mav.model.vehicle_faults import parse_vehicle_faults

STEP = 0.0025
RATE = 50.0


def fly(fault: str, until: float, noise=(0.0, 0.0, 0.0, 0.0), answer: bool = True, probe: bool = True,
        jumped_at: float | None = None):
    """The square from its start pose with `fault` in the plant's thrusters (PWM -> T200 thrust -> the fault ->
    first-order lag -> B f), the fuzzy law at RATE on the measured state, the watch told the estimate jumped at
    `jumped_at`: (verdicts as (t, Verdict), the watch, position errors (t, m))."""
    mission = load("missions/square.yaml")
    vehicle = load_vehicle(None)
    plant = Plant(vehicle, Environment(disturbance=mission.environment.disturbance, noise=np.array(noise)),
                  eta0=np.array(mission.start_pose), seed=3)
    law = Controller(vehicle, load_settings("fuzzy"))
    actuation = Actuation(vehicle, 40.0, probe=probe)
    period = 1.0 / RATE
    health = ThrusterHealth(law.model, actuation.allocator.matrix, period, vehicle.thruster_time_constant)
    faults = parse_vehicle_faults(fault.split(",") if fault else [])
    matrix, thrust = actuation.allocator.matrix.copy(), np.zeros(8)
    lag = 1.0 - np.exp(-STEP / vehicle.thruster_time_constant)
    found, errors = [], []
    for k in range(int(until * RATE)):
        t = k * period
        eta, nu = plant.measured()
        if jumped_at is not None and abs(t - jumped_at) < 0.5 * period:
            health.estimate_jumped(t)
        health.observe(t, np.r_[eta, nu])
        for verdict in health.verdicts(t):
            found.append((t, verdict))
            if answer:
                actuation.set_gain(verdict.thruster - 1, verdict.gain)
                health.answered(verdict)
        reference = mission.reference(t)
        thrusts, pwm, _ = actuation.command(law.step(eta, nu, reference, period).tau, t)
        health.told(t, actuation.delivered)
        gain, stuck = faults.thruster_effect(t)
        commanded = actuation.t200.thrust(np.where(np.isnan(stuck), pwm, stuck), actuation.voltage) * gain
        for _ in range(round(period / STEP)):
            thrust += (commanded - thrust) * lag
            plant.step(matrix @ thrust, STEP)
        errors.append((t, float(np.linalg.norm(plant.eta[:3] - reference[:3]))))
    return found, health, np.array(errors)


def test_a_healthy_vehicle_has_no_faulty_thruster_even_with_sensor_noise():
    found, health, _ = fly("", 40.0, noise=(0.02, 0.009, 0.01, 0.005))
    assert found == []
    assert np.all(health.evidence < EVIDENCE)         # no thruster's hypothesis explains the motion better


@pytest.mark.parametrize("fault, kinds, within", [
    ("thruster=3:dead@60s", {"dead"}, 2.0),                # the targets: on the square's second side
    ("thruster=3:stuck=1700@60s", {"stuck", "dead"}, 3.0),
    ("thruster=3:weak=0.3@60s", {"weak"}, 3.0),
    ("thruster=3:reversed@60s", {"reversed", "stuck"}, 3.0),
])
def test_the_failed_thruster_is_named_in_time_and_the_square_goes_on(fault, kinds, within):
    found, _, errors = fly(fault, 72.0)
    assert found, "not detected"
    t, verdict = found[0]
    assert verdict.thruster == 3 and verdict.kind in kinds, verdict.describe()
    assert 60.0 <= t <= 60.0 + within
    after = errors[errors[:, 0] > t + 3.0, 1]
    assert np.sqrt(np.mean(after ** 2)) < 0.02          # re-allocated: back on the path within 3 s


def test_without_the_answer_a_reversed_thruster_ruins_the_path():
    """The same fault, found but not answered: the comparison that shows the answer is what keeps the path."""
    _, _, errors = fly("thruster=3:reversed@60s", 72.0, answer=False)
    after = errors[errors[:, 0] > 65.0, 1]
    assert np.sqrt(np.mean(after ** 2)) > 0.05


def test_the_allocation_around_a_thruster_gives_the_wrench_asked():
    actuation = Actuation(load_vehicle(None), 40.0, pretension=True)
    tau = np.array([10.0, -5.0, 8.0, 0.5, -0.3, 1.0])
    for i, gain in ((2, 0.0), (5, 0.4), (0, -1.0)):
        actuation.set_gain(i, gain)
        thrusts, _, info = actuation.command(tau)
        given = thrusts * actuation.gains                  # what each thruster gives when told `thrusts`
        assert np.allclose(actuation.allocator.wrench(given), tau, atol=1e-6)
        assert not info.saturated
    assert thrusts[2] == 0.0                               # a thruster left out is told nothing


def test_the_probe_has_no_net_wrench_and_moves_every_horizontal_thruster_only():
    actuation = Actuation(load_vehicle(None), 40.0, pretension=False, diffuse=False, probe=True)
    tau = np.array([5.0, 0.0, 3.0, 0.0, 0.0, 0.2])
    plain = actuation.allocator.thrusts(tau)[0]
    probed = np.array([actuation.command(tau, t)[0] for t in np.linspace(0.0, 2.0, 9)])
    assert np.allclose(actuation.allocator.wrench(probed), tau, atol=1e-9)
    swing = np.ptp(probed - plain, axis=0)
    assert np.all(swing[:4] > 0.5) and np.all(swing[4:] < 1e-9)   # motors 1-4 horizontal, 5-8 vertical


def test_any_seven_thrusters_keep_all_six_axes_with_half_the_authority_on_the_lost_ones():
    actuation = Actuation(load_vehicle(None), 40.0)
    full = actuation.allocator.authority()
    for i in range(8):
        actuation.set_gain(i, 0.0)
        share = actuation.allocator.authority() / full
        assert np.all(share > 0.45) and np.sum(share < 0.99) == 3
        actuation.set_gain(i, 1.0)


def test_after_an_estimate_jump_no_thruster_is_named_until_the_motion_settles():
    """A jump of the position estimate (an EKF reset) steps its velocity and the law answers with a burst of thrust
    that any hypothesis can partly fit: the watch starts its scores again and names nothing for SETTLE s. A thruster
    that really died just before is still named after it."""
    found, _, _ = fly("thruster=3:dead@60s", 60.0 + SETTLE + 4.0, jumped_at=60.2)
    assert found, "not detected after the quiet time"
    t, verdict = found[0]
    assert t >= 60.2 + SETTLE and verdict.thruster == 3
