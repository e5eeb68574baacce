"""Physics through the protocol: thruster patterns sent as RC overrides to passthrough outputs reach the steady
motion that the T200 map, the allocation matrix and the damping predict. The bridge runs in-process (the embedded
API) on a real UDP socket; speeds are read from its telemetry, the thrust is computed at the battery voltage it
reports."""

from __future__ import annotations

import math

import numpy as np
import pytest
from bridge_helpers import BridgeThread, Gcs, mavutil

from rov_mav.model.thrusters import Allocator, allocation_matrix, load_t200

pytestmark = pytest.mark.process      # starts a process or the bridge (tests/conftest.py)

SPEEDUP = 10.0
mav = mavutil.mavlink


@pytest.fixture
def flown(request):
    """(bridge, gcs): passthrough on SERVO1..8, 50 Hz attitude and position, heartbeats and overrides pumped."""
    depth = getattr(request, "param", 0.0)
    with BridgeThread(SPEEDUP, start_depth=depth) as running:
        gcs = Gcs(running.port, SPEEDUP, rate=5.0)
        try:
            gcs.connect()
            for n in range(1, 9):
                gcs.set_param(f"SERVO{n}_FUNCTION", 50 + n, mav.MAV_PARAM_TYPE_INT16)
            gcs.set_interval(mav.MAVLINK_MSG_ID_ATTITUDE, 50)
            gcs.set_interval(mav.MAVLINK_MSG_ID_LOCAL_POSITION_NED, 50)
            gcs.override = [1500] * 8
            gcs.start_pump()
            yield running.bridge, gcs
        finally:
            gcs.close()


def fly(gcs: Gcs, pwm, settle: float = 8.0, average: float = 2.0) -> dict[str, np.ndarray]:
    """Hold `pwm` (8,) for `settle` simulated s, then average over `average` s: attitude (roll, pitch, yaw, p, q, r),
    position (x, y, z, vx, vy, vz NED), body (horizontal velocity in the body axes u, v) and the battery voltage."""
    gcs.override = [int(p) for p in pwm]
    start = gcs.sim_time_now()
    gcs.recv("ATTITUDE", cond=lambda m: m.time_boot_ms / 1000 > start + settle)
    rows: dict[str, list] = {"attitude": [], "position": [], "voltage": [], "body": []}
    end = start + settle + average
    while True:
        m = gcs.recv(["ATTITUDE", "LOCAL_POSITION_NED", "BATTERY_STATUS"])
        if m.get_type() == "ATTITUDE":
            if m.time_boot_ms / 1000 > end:
                break
            rows["attitude"].append([m.roll, m.pitch, m.yaw, m.rollspeed, m.pitchspeed, m.yawspeed])
            yaw = m.yaw
        elif m.get_type() == "LOCAL_POSITION_NED":
            rows["position"].append([m.x, m.y, m.z, m.vx, m.vy, m.vz])
            if rows["attitude"]:
                c, si = math.cos(yaw), math.sin(yaw)
                rows["body"].append([c * m.vx + si * m.vy, -si * m.vx + c * m.vy])
        else:
            rows["voltage"].append(m.voltages[0] / 1000)
    return {k: np.mean(v, axis=0) for k, v in rows.items()}


def quadratic_speed(force: float, linear: float, quadratic: float) -> float:
    """The speed where linear + quadratic drag balance `force` (sign of force)."""
    f = abs(force)
    speed = f / linear if quadratic == 0 else (-linear + math.sqrt(linear**2 + 4 * quadratic * f)) / (2 * quadratic)
    return math.copysign(speed, force)


def wrench(vehicle, pwm, voltage: float) -> np.ndarray:
    B = allocation_matrix(vehicle.thruster_positions, vehicle.thruster_directions)
    return B @ load_t200().thrust(np.asarray(pwm, dtype=float), round(voltage, 2))


def test_four_verticals_together_heave_down_at_the_drag_balance_speed(flown):
    bridge, gcs = flown
    pwm = [1500] * 4 + [1620] * 4
    s = fly(gcs, pwm)
    tau = wrench(bridge.vehicle, pwm, s["voltage"])
    assert np.allclose(tau[[0, 1, 3, 4, 5]], 0, atol=0.02) and tau[2] > 10   # a few mm off symmetric
    w = quadratic_speed(tau[2], bridge.vehicle.linear_damping[2], bridge.vehicle.quadratic_damping[2])
    assert s["position"][5] == pytest.approx(w, rel=0.02)            # NED vz: down
    assert np.allclose(s["position"][3:5], 0, atol=5e-3) and np.allclose(s["attitude"][:2], 0, atol=0.01)


def test_one_four_against_two_three_yaw_clockwise_at_the_drag_balance_rate(flown):
    bridge, gcs = flown
    pwm = [1600, 1400, 1400, 1600, 1500, 1500, 1500, 1500]
    s = fly(gcs, pwm)
    tau = wrench(bridge.vehicle, pwm, s["voltage"])
    assert np.allclose(tau[:5], 0, atol=0.02) and tau[5] > 1      # the geometry is a few mm off symmetric
    r = quadratic_speed(tau[5], bridge.vehicle.linear_damping[5], bridge.vehicle.quadratic_damping[5])
    assert s["attitude"][5] == pytest.approx(r, rel=0.02)            # +psi: clockwise seen from above
    assert np.allclose(s["attitude"][3:5], 0, atol=1e-3) and np.allclose(s["position"][3:6], 0, atol=2e-3)


def test_forward_thrust_with_its_pitch_moment_compensated_reaches_the_drag_balance_speed(flown):
    bridge, gcs = flown
    voltage = gcs.recv("BATTERY_STATUS").voltages[0] / 1000
    thrusts, info = Allocator.for_vehicle(bridge.vehicle, voltage).thrusts(np.array([20.0, 0, 0, 0, 0, 0]))
    assert not info.saturated and thrusts[4] > 0 > thrusts[6]        # front verticals down, rear ones up
    pwm = np.rint(load_t200().pwm(thrusts, round(voltage, 2))).astype(int)
    s = fly(gcs, pwm)
    tau = wrench(bridge.vehicle, pwm, s["voltage"])
    u = quadratic_speed(tau[0], bridge.vehicle.linear_damping[0], bridge.vehicle.quadratic_damping[0])
    assert u > 0.25
    assert abs(s["attitude"][1]) < math.radians(3)
    # PWMs are whole microseconds: the residual yaw moment (~0.01 N m against little yaw damping) turns the
    # vehicle slowly, so compare in the body axes
    assert s["body"][0] == pytest.approx(u, rel=0.05) and abs(s["body"][1]) < 0.2 * u   # sideslip of the turn
    assert abs(s["position"][5]) < 0.03
    _, eta, nu = bridge.truth()
    assert nu[0] == pytest.approx(u, rel=0.05) and math.hypot(eta[0], eta[1]) > 2.0


def test_forward_thrust_alone_pitches_the_nose_up_in_open_loop(flown):
    _, gcs = flown
    s = fly(gcs, [1400, 1400, 1600, 1600, 1500, 1500, 1500, 1500], settle=5.0, average=1.0)
    assert s["attitude"][1] > math.radians(20)                       # 0.085 m thrust offset vs 1 cm of BG


@pytest.mark.parametrize("flown", [5.0], indirect=True)
def test_neutral_pwm_keeps_the_vehicle_still_at_depth(flown):
    bridge, gcs = flown
    assert gcs.command(mav.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == mav.MAV_RESULT_ACCEPTED
    s = fly(gcs, [1500] * 8, settle=10.0, average=2.0)
    assert np.allclose(s["position"], [0, 0, 5, 0, 0, 0], atol=1e-4)
    assert np.allclose(s["attitude"], 0, atol=1e-4)
    _, eta, nu = bridge.truth()
    assert np.allclose(eta, [0, 0, 5, 0, 0, 0], atol=1e-4) and np.allclose(nu, 0, atol=1e-4)
