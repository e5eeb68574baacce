"""Vehicle faults on the built-in vehicle, met as ArduSub meets them: thruster faults in the physics, reboots
(a brown-out or MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN), a leak, a sagging battery, a lost position source, a failed depth
sensor, and SURFACE mode.

First the pieces (physics, the failsafes on an ArduSub, the navigation), then whole bridges stepped by hand with a
recording link (exact timelines on the vehicle's clock), then bridges in a thread over real UDP/TCP with pymavlink
(what a ground station sees), and the command line."""

from __future__ import annotations

import socket
import subprocess
import time

import numpy as np
import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink
from bridge_helpers import ROV_MAV, WAIT, BridgeProcess, BridgeThread, Gcs, free_port, mavutil

from rov_mav.model.dynamics import rotation
from rov_mav.model.navigation import PRESETS as NAVIGATION_PRESETS
from rov_mav.model.plant import Plant
from rov_mav.model.thrusters import thruster_curve
from rov_mav.model.vehicle import load_vehicle
from rov_mav.model.vehicle_faults import parse_vehicle_faults
from sim_bridge.hardware import boot
from sim_bridge.navigation import aiding as navigation
from sim_bridge.autopilot.ardusub import MODES, ArduSub
from sim_bridge.hardware.battery import Battery
from sim_bridge.config import BridgeConfig
from sim_bridge.autopilot.failsafes import Readings
from sim_bridge.autopilot.params import Params
from sim_bridge.hardware.physics import Physics
from sim_bridge.server import Bridge

mav = mavutil.mavlink
STEP = 0.0025
SPEEDUP = 10.0
QUIET = {"FS_PILOT_INPUT": 0, "FS_GCS_ENABLE": 0}      # no pilot or GCS to keep the other failsafes away
CRITICAL, WARNING, INFO = mav.MAV_SEVERITY_CRITICAL, mav.MAV_SEVERITY_WARNING, mav.MAV_SEVERITY_INFO


def faults(text: str):
    return parse_vehicle_faults(text.split(","))


# -- physics ---------------------------------------------------------------------------------------------------


def physics_of(text: str = "") -> Physics:
    vehicle = load_vehicle()
    plant = Plant(vehicle, eta0=np.array([0, 0, 5.0, 0, 0, 0]))
    return Physics(vehicle, plant, Battery(), thruster_curve(vehicle), STEP, faults(text) if text else None)


PWM = np.array([1700, 1300, 1650, 1400, 1600, 1550, 1450, 1350], dtype=np.int32)


def fly_physics(physics: Physics, pwm=PWM, seconds: float = 0.5, t0: float = 0.0) -> None:
    for k in range(round(seconds / STEP)):
        physics.step(pwm, t0 + k * STEP)


def test_a_dead_thruster_gives_no_thrust_draws_no_current_and_leaves_the_others_column_of_b():
    healthy, dead = physics_of(), physics_of("thruster=3:dead@0s")
    fly_physics(healthy)
    fly_physics(dead)
    assert dead.thrusts[2] == 0 and abs(healthy.thrusts[2]) > 5
    others = [i for i in range(8) if i != 2]
    assert np.allclose(dead.thrusts[others], healthy.thrusts[others], rtol=0.01)    # at a slightly higher voltage
    b_without_3 = np.delete(dead.matrix, 2, axis=1)
    assert np.allclose(dead.tau, b_without_3 @ dead.thrusts[others])
    voltage = round(dead.battery.voltage, 2)
    lost = float(dead.t200.current(np.array([1650.0]), voltage)[0])
    assert healthy.battery.current - dead.battery.current == pytest.approx(lost, rel=0.05)


def test_stuck_weak_and_reversed_thrusters_from_their_time_on():
    physics = physics_of("thruster=1:stuck=1700@1s,thruster=2:weak=0.3@1s,thruster=5:reversed@1s")
    healthy = physics_of()
    fly_physics(physics, seconds=0.9)
    fly_physics(healthy, seconds=0.9)
    assert np.allclose(physics._commanded, healthy._commanded)          # nothing before 1 s
    fly_physics(physics, seconds=0.5, t0=1.0)
    fly_physics(healthy, seconds=0.5, t0=1.0)
    v = round(physics.battery.voltage, 2)
    assert physics._commanded[1] == pytest.approx(0.3 * healthy._commanded[1], rel=1e-3)
    assert physics._commanded[4] == pytest.approx(-healthy._commanded[4], rel=1e-3)
    silent = np.zeros(8, dtype=np.int32)                                 # no pulse at all (a rebooting autopilot)
    fly_physics(physics, pwm=silent, seconds=0.5, t0=2.0)
    assert physics._commanded[0] == pytest.approx(float(physics.t200.thrust(np.array([1700.0]), v)[0]), rel=0.02)
    assert np.all(physics._commanded[1:] == 0)


# -- the failsafes on an ArduSub -------------------------------------------------------------------------------


def vehicle(firmware: str = "4.7", **params) -> ArduSub:
    p = Params(firmware)
    for name, value in {**QUIET, **params}.items():
        p.set(name, value)
    return ArduSub(p)


def run(sub: ArduSub, t0: float, t1: float, sensors: Readings, state=None) -> None:
    for k in range(round((t1 - t0) / STEP)):
        sub.update(t0 + k * STEP, state, sensors)


def texts(sub: ArduSub) -> list[str]:
    return [text for _, text in sub.texts]


def test_leak_warns_every_20_s_of_uptime_and_surfaces_only_if_armed_when_first_found():
    sub = vehicle(FS_LEAK_ENABLE=2)
    wet = Readings(leak=True)
    sub.arm(True)
    run(sub, 0.0, 19.9, wet)
    assert sub.mode == MODES["SURFACE"] and sub.failsafes.leak          # acted at once ...
    assert "Leak Detected" not in texts(sub)                            # ... the first text only after 20 s
    run(sub, 19.9, 45.0, wet)
    assert sub.texts.count((CRITICAL, "Leak Detected")) == 2            # 20.x s and 40.x s
    assert sub.system_status() == mav.MAV_STATE_CRITICAL

    sub = vehicle(FS_LEAK_ENABLE=2)
    run(sub, 0.0, 1.0, wet)                                             # found while disarmed: latched, no action
    sub.arm(True)
    run(sub, 1.0, 5.0, wet)
    assert sub.mode == MODES["MANUAL"]
    sub = vehicle()                                                     # default 1: warn only
    sub.arm(True)
    run(sub, 0.0, 21.0, wet)
    assert sub.mode == MODES["MANUAL"] and (CRITICAL, "Leak Detected") in sub.texts


def test_leak_makes_heartbeat_critical_in_47_not_in_45():
    for firmware, status in (("4.7", mav.MAV_STATE_CRITICAL), ("4.5", mav.MAV_STATE_STANDBY)):
        sub = vehicle(firmware)
        run(sub, 0.0, 1.0, Readings(leak=True))
        assert sub.system_status() == status, firmware


def test_battery_low_after_its_timer_then_critical_surfaces_with_its_text():
    sub = vehicle(BATT_LOW_VOLT=14.0, BATT_CRT_VOLT=13.0, BATT_LOW_TIMER=2, BATT_FS_LOW_ACT=1, BATT_FS_CRT_ACT=3)
    low = Readings(voltage=13.5, consumed_mah=1234.4)
    run(sub, 0.0, 5.0, low)
    assert sub.failsafes.battery == 0 and not sub.texts                 # disarmed: the monitor does not check
    sub.arm(True, checks=False)                                         # forced: the arming checks see it low
    run(sub, 5.0, 7.0, low)
    assert sub.failsafes.battery == 0                                   # 2 s not yet exceeded
    run(sub, 7.0, 7.3, low)
    assert texts(sub) == ["Battery 1 is low 13.50V used 1234 mAh"] and sub.texts[0][0] == WARNING
    assert sub.mode == MODES["MANUAL"] and sub.system_status() == mav.MAV_STATE_CRITICAL
    run(sub, 7.3, 10.0, Readings(voltage=12.5, consumed_mah=1300))
    assert texts(sub)[-1] == "Battery 1 is critical 12.50V used 1300 mAh" and sub.mode == MODES["SURFACE"]
    run(sub, 10.0, 12.0, Readings(voltage=16.0))                         # voltage back: still failsafed
    assert sub.failsafes.battery_failsafed and sub.system_status() == mav.MAV_STATE_CRITICAL


def test_battery_actions_follow_their_priority_and_capacity_acts_at_once():
    sub = vehicle(BATT_LOW_MAH=5000, BATT_CRT_MAH=2000, BATT_FS_LOW_ACT=2, BATT_FS_CRT_ACT=3)
    sub.arm(True)
    run(sub, 0.0, 0.2, Readings(consumed_mah=13500))                     # 4500 mAh left: low at once, disarm
    assert not sub.armed and "Battery 1 is low" in texts(sub)[0]
    sub.arm(True, checks=False)                                         # forced: the arming checks see it low
    run(sub, 0.2, 0.4, Readings(consumed_mah=16500))                     # critical: SURFACE ranks below disarm
    assert "critical" in texts(sub)[-1] and sub.mode == MODES["MANUAL"] and sub.armed


def test_ekf_failsafe_after_2_s_of_bad_variance_warns_after_20_s_of_uptime_and_disarms_with_action_2():
    sub = vehicle(FS_EKF_ACTION=2)
    sub.arm(True)
    bad = Readings(velocity_variance=0.9)
    run(sub, 0.0, 1.9, bad)
    assert sub.armed and not sub.failsafes.ekf
    run(sub, 1.9, 2.2, bad)
    assert not sub.armed and sub.failsafes.ekf and "EKF bad" not in texts(sub)   # no text in the first 20 s
    run(sub, 2.2, 3.0, Readings())
    assert not sub.failsafes.ekf
    sub.arm(True)
    run(sub, 30.0, 32.5, Readings(compass_variance=0.8))                  # at the threshold counts as bad
    assert (WARNING, "EKF bad") in sub.texts and not sub.armed
    off = vehicle()                                                     # default FS_EKF_ACTION 0: nothing
    off.arm(True)
    run(off, 0.0, 5.0, bad)
    assert off.armed and not off.failsafes.ekf


def test_depth_sensor_failure_reports_once_and_leaves_depth_modes_for_manual():
    sub = vehicle()
    state = (np.array([0, 0, 5.0, 0, 0, 0]), np.zeros(6))
    assert sub.set_mode(MODES["ALT_HOLD"])
    sub.arm(True)
    run(sub, 0.0, 1.0, Readings(depth_healthy=False), state)
    assert sub.mode == MODES["MANUAL"] and sub.texts.count((CRITICAL, "Depth sensor error!")) == 1
    assert sub.system_status() == mav.MAV_STATE_CRITICAL                # 4.7: sensor_health is a failsafe
    sub.texts.clear()
    assert not sub.set_mode(MODES["ALT_HOLD"])
    assert texts(sub) == ["Depth sensor error.", "Flight mode change failed ALT_HOLD"]
    assert sub.set_mode(MODES["STABILIZE"])
    gone = vehicle()                                                    # none found at boot: no failsafe at all
    run(gone, 0.0, 1.0, Readings(depth_healthy=False, depth_present=False))
    assert not gone.texts and not gone.set_mode(MODES["ALT_HOLD"])
    assert texts(gone) == ["Depth sensor is not connected.", "Flight mode change failed ALT_HOLD"]


def test_position_modes_need_the_ekf_position():
    sub = vehicle()
    sub.position_ok_flags = (False, False)
    assert not sub.set_mode(MODES["POSHOLD"]) and not sub.set_mode(MODES["GUIDED"])
    assert texts(sub) == ["Mode change failed: POSHOLD requires position",
                          "Mode change failed: GUIDED requires position"]
    sub.position_ok_flags = (False, True)                               # disarmed, a predicted position will do
    assert sub.set_mode(MODES["POSHOLD"])


# -- SURFACE ---------------------------------------------------------------------------------------------------


def surface_flight(firmware: str, seconds: float, sensors: Readings = Readings(), depth: float = 3.0):
    vehicle_ = load_vehicle()
    plant = Plant(vehicle_, eta0=np.array([0, 0, depth, 0, 0, 0.0]))
    physics = Physics(vehicle_, plant, Battery(), thruster_curve(vehicle_), STEP)
    sub = vehicle(firmware)
    sub.update(0.0, (plant.eta, plant.nu), sensors)
    entered = sub.set_mode(MODES["SURFACE"])
    sub.arm(True, checks=False)       # forced (a missing depth sensor fails the arming checks)
    modes = []
    for k in range(round(seconds / STEP)):
        sub.update(k * STEP, (plant.eta, plant.nu), sensors)
        physics.step(sub.servo_outputs()[:8], k * STEP)
        modes.append(sub.mode)
    return entered, sub, plant, modes


def test_surface_rises_and_holds_depth_at_the_surface_in_alt_hold():
    entered, sub, plant, modes = surface_flight("4.7", 20.0)
    assert entered and MODES["SURFACE"] in modes
    assert sub.mode == MODES["ALT_HOLD"] and sub.armed                   # SURFACE_COMPLETE: no disarm
    assert plant.eta[2] == pytest.approx(0.10, abs=0.08) and abs(plant.nu[2]) < 0.05
    climbing = modes.index(MODES["ALT_HOLD"]) * STEP
    assert 3.0 < climbing < 12.0                                       # 2.9 m at a few decimetres a second


def test_surface_without_a_depth_sensor_refused_in_45_and_rises_on_its_thrust_in_47():
    none = Readings(depth_present=False)
    entered, sub, _, _ = surface_flight("4.5", 0.1, none)
    assert not entered and texts(sub)[-2:] == ["Depth sensor is not connected.", "Flight mode change failed SURFACE"]
    entered, sub, plant, modes = surface_flight("4.7", 6.0, none)
    assert entered and set(modes) == {MODES["SURFACE"]}                 # no surface detection, no ALT_HOLD
    assert plant.eta[2] < 3.0 - 0.2 and plant.nu[2] < -0.03             # 10 % of throttle up: slowly
    assert "SFC_NOBARO_THST" not in Params("4.5") and sub.params["SFC_NOBARO_THST"] == 10


# -- navigation ------------------------------------------------------------------------------------------------


def test_navigation_stages_and_return():
    nav = navigation.Aiding()
    measured = (np.array([3.0, 4.0, 5.0, 0, 0, 0.2]), np.array([0.5, 0.1, 0, 0, 0, 0]))
    changes = []                                                        # (flags, t, eta, nu, variances)
    for k in range(round(30.0 / STEP)):
        t = k * STEP
        eta, nu = nav.update(t, not 10.0 <= t < 28.0, True, measured)
        if not changes or changes[-1][0] != nav.flags(t):
            changes.append((nav.flags(t), t, eta.copy(), nu.copy(), nav.variances(t)))
    assert [c[0] for c in changes] == [831, 37, 165, 831]
    assert changes[1][1] == pytest.approx(17.0, abs=0.01) and changes[2][1] == pytest.approx(25.0, abs=0.01)
    assert changes[2][4][0] == pytest.approx(0.05 + 0.1 * 15.0, abs=0.01) and changes[3][1] == pytest.approx(28.0)
    held_eta, held_nu = changes[2][2], changes[2][3]
    assert np.allclose(held_eta[:2], [3.0, 4.0]) and np.allclose((rotation(held_eta) @ held_nu[:3])[:2], 0)
    assert nav.texts == [(WARNING, "EKF3 IMU0 stopped aiding"), (INFO, "EKF3 IMU0 is using external nav data"),
                         (INFO, "EKF3 IMU0 initial pos NED = 3.0,4.0,5.0 (m)")]
    assert nav.position_ok(29.0, armed=True)
    fresh = navigation.Aiding(navigation_ok=False)                  # booted without it: AID_NONE, silent
    fresh.update(0.0, False, True, measured)
    assert fresh.flags(0.0) == 165 and not fresh.texts and not fresh.position_ok(0.0, armed=False)


# -- whole bridges, stepped by hand ---------------------------------------------------------------------------


class Recorder:
    """A link stand-in: records what the bridge sends (with the vehicle time), hands it queued messages."""

    channel = 0

    def __init__(self, bridge: Bridge):
        self.bridge = bridge
        self.sent: list[tuple[float, object]] = []
        self.inbox: list = []
        self.restarts: list[int] = []
        self.dropped = 0

    def send(self, msg) -> None:
        self.sent.append((round(self.bridge.t, 4), msg))

    def send_as(self, msg, source: tuple[int, int]) -> None:
        self.send(msg)

    def receive(self) -> list:
        out, self.inbox = self.inbox, []
        return out

    def deliver(self) -> None:
        pass

    def sockets(self) -> list:
        return []

    def restart(self, sysid: int) -> None:
        self.restarts.append(sysid)

    def drop_clients(self) -> None:
        self.dropped += 1

    def close(self) -> None:
        pass

    def of(self, kind: str, since: float = -1.0) -> list[tuple[float, object]]:
        return [(t, m) for t, m in self.sent if m.get_type() == kind and t >= since]

    def texts(self) -> list[tuple[float, str]]:
        return [(t, m.text) for t, m in self.of("STATUSTEXT")]


def text_at(link: Recorder, text: str) -> float:
    """The vehicle time of the only STATUSTEXT `text`."""
    (t,) = [t for t, x in link.texts() if x == text]
    return t


def stepped(text: str, firmware: str = "4.7", **config) -> tuple[Bridge, Recorder]:
    params = {**QUIET, **config.pop("params", {})}
    b = Bridge(BridgeConfig(endpoints=(), firmware=firmware, vehicle_faults=faults(text) if text else None,
                            params=params, **config))
    link = Recorder(b)
    b.links = [link]
    b._start_streams()
    return b, link


def advance(b: Bridge, seconds: float) -> None:
    for _ in range(round(seconds / b.physics.h)):
        b._step()


_GCS = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
_PARSER = mavlink.MAVLink(None)


def from_gcs(name: str, *fields):
    """A message as a ground station (255/190) sends it, parsed back (with its header)."""
    return _PARSER.parse_buffer(getattr(_GCS, f"{name}_encode")(*fields).pack(_GCS))[0]


def test_a_brown_out_silences_the_vehicle_then_it_boots_fresh_on_its_stored_parameters():
    b, link = stepped("reboot@5s", start_depth=2.0)
    b.params.set("SERVO1_FUNCTION", 51)                                  # a PARAM_SET: stored
    b.params.set("MAV1_EXTRA1", 2, save=False)                           # a REQUEST_DATA_STREAM: RAM only
    b.schedulers[0].set_interval("VFR_HUD", 1_000_000, 0.0)
    b._params_changed(0.0)
    b.sub.rc_override(255, [1600] * 8 + [0] * 10, 0.0)
    b.sub.arm(True)
    assert b.sub.set_mode(MODES["STABILIZE"])
    advance(b, 4.99)
    assert b.sub.armed and b.schedulers[0].intervals["VFR_HUD"] == 1.0
    before = link.of("ATTITUDE")[-1][1].time_boot_ms
    advance(b, 2.0)                                                      # off, then initialising
    off = b.boot.start * STEP - boot.FIRMWARE_START
    assert off == pytest.approx(5.0, abs=0.003)
    assert link.dropped == 1 and link.restarts == [1] and not b.servo.any()
    assert np.all(b.physics._commanded == 0)                             # no pulse: no thrust
    advance(b, 1.5)
    assert not [m for t, m in link.sent if off < t < off + 2.0]          # 2 s of silence
    booting = [(t, m) for t, m in link.sent if off + 2.0 <= t < off + boot.BOOT_TIME]
    assert [m.get_type() for _, m in booting] == ["HEARTBEAT", "SYS_STATUS"]
    hb, sys_status = booting[0][1], booting[1][1]
    assert hb.system_status == mav.MAV_STATE_BOOT and hb.custom_mode == MODES["MANUAL"] and not hb.base_mode & 128
    assert not sys_status.onboard_control_sensors_health & mav.MAV_SYS_STATUS_SENSOR_3D_GYRO
    assert text_at(link, "ArduPilot Ready") == pytest.approx(off + boot.BOOT_TIME, abs=0.003)
    after = [m for t, m in link.of("ATTITUDE", since=off + boot.BOOT_TIME)]
    assert after and 2000 <= after[0].time_boot_ms < 2100 and after[0].time_boot_ms < before
    assert not b.sub.armed and b.sub.mode == MODES["MANUAL"] and b.sub.system_status() == mav.MAV_STATE_STANDBY
    assert b.params["SERVO1_FUNCTION"] == 51 and b.params["MAV1_EXTRA1"] == 10     # the stored rate
    assert b.schedulers[0].intervals["VFR_HUD"] == 0.1                   # SET_MESSAGE_INTERVAL forgotten
    assert b.sub.rc.radio_in[0] == 1500 and b.t == pytest.approx(8.49)  # the physics clock runs on ...
    assert b.uptime == pytest.approx(b.t - off - boot.FIRMWARE_START)   # ... the autopilot's restarted


def test_preflight_reboot_refused_armed_unless_forced_acked_before_the_power_goes():
    b, link = stepped("")
    cmd = mav.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN

    def ack(p1: float, p6: float = 0.0, target_component: int = 1) -> int:
        link.sent.clear()
        link.inbox.append(from_gcs("command_long", 1, target_component, cmd, 0, p1, 0, 0, 0, 0, p6, 0))
        b._receive()
        return [m for _, m in link.of("COMMAND_ACK")][0].result

    b.sub.arm(True)
    assert ack(1) == mav.MAV_RESULT_FAILED and b.boot.reboots == 0
    assert ack(2) == mav.MAV_RESULT_FAILED                               # armed is checked first
    b.sub.arm(False)
    assert ack(2) == mav.MAV_RESULT_UNSUPPORTED and ack(0) == mav.MAV_RESULT_UNSUPPORTED
    b.sub.arm(True)
    assert ack(1, p6=20190226) == mav.MAV_RESULT_ACCEPTED and b.boot.reboots == 1
    assert b.boot.phase(b.steps) == boot.OFF and link.dropped == 1
    link.inbox.append(from_gcs("command_long", 1, 1, mav.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0))
    link.sent.clear()
    b._receive()
    assert not link.sent and b.messages_ignored == 1                    # off: nothing is handled
    advance(b, boot.BOOT_TIME + 0.1)
    assert b.boot.phase(b.steps) == boot.RUNNING and not b.sub.armed
    assert ack(3) == mav.MAV_RESULT_ACCEPTED and b.boot.reboots == 2     # 3 (bootloader) reboots as SITL


def test_depth_sensor_failure_freezes_the_bar30_and_a_reboot_finds_no_depth_sensor():
    b, link = stepped("depth-sensor@2s,reboot@6s", start_depth=4.0)
    b.sub.arm(True)
    assert b.sub.set_mode(MODES["ALT_HOLD"])
    advance(b, 1.99)
    assert link.of("SCALED_PRESSURE2")
    advance(b, 1.0)
    assert text_at(link, "Depth sensor error!") == pytest.approx(2.0, abs=0.05) and b.sub.mode == MODES["MANUAL"]
    frozen = {m.press_abs for _, m in link.of("SCALED_PRESSURE2", since=2.01)}
    assert len(frozen) == 1
    status = link.of("SYS_STATUS", since=2.1)[-1][1]
    assert status.onboard_control_sensors_present & mav.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
    assert not status.onboard_control_sensors_health & mav.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
    advance(b, 7.0)                                                      # rebooted at 6 s, running from 9 s
    assert not link.of("SCALED_PRESSURE2", since=6.01)
    status = link.of("SYS_STATUS", since=9.0)[-1][1]
    assert not status.onboard_control_sensors_present & mav.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
    assert not b.sub.set_mode(MODES["ALT_HOLD"]) and "Depth sensor is not connected." in [t for _, t in b.sub.texts]


def test_battery_sag_warns_and_surfaces_and_shows_in_battery_status_and_sys_status():
    b, link = stepped("battery=0.5V/s@1s", start_depth=3.0,
                      params={"BATT_CRT_VOLT": 15.0, "BATT_LOW_TIMER": 1, "BATT_FS_CRT_ACT": 3})
    b.sub.arm(True)
    advance(b, 8.0)                                                      # 16.8 - 0.5 (t - 1) < 15 from 4.6 s
    (t, text), = [(t, x) for t, x in link.texts() if x.startswith("Battery")]
    assert 5.5 < t < 6.0 and text.startswith("Battery 1 is critical 1") and text.endswith("mAh")
    assert b.sub.mode in (MODES["SURFACE"], MODES["ALT_HOLD"])
    assert link.of("BATTERY_STATUS")[-1][1].charge_state == mav.MAV_BATTERY_CHARGE_STATE_CRITICAL
    status = link.of("SYS_STATUS")[-1][1]
    assert not status.onboard_control_sensors_health & mav.MAV_SYS_STATUS_SENSOR_BATTERY
    assert link.of("HEARTBEAT")[-1][1].system_status == mav.MAV_STATE_CRITICAL


def test_navigation_lost_stops_local_position_and_shows_in_ekf_status_report():
    b, link = stepped("navigation-lost@1s+20s")
    advance(b, 30.0)
    report = {round(t): m.flags for t, m in link.of("EKF_STATUS_REPORT")}
    assert report[1] == 831 and report[9] == 37 and report[17] == 165 and report[22] == 831
    local = [t for t, _ in link.of("LOCAL_POSITION_NED")]
    assert not [t for t in local if 16.01 <= t < 21.0] and [t for t in local if t >= 21.0]
    assert [t for t, _ in link.of("GLOBAL_POSITION_INT") if 16.01 <= t < 21.0]          # still sent
    assert text_at(link, "EKF3 IMU0 stopped aiding") == pytest.approx(16.0, abs=0.01)
    variance = [m.velocity_variance for t, m in link.of("EKF_STATUS_REPORT") if 10 <= t < 11]
    assert variance[0] == pytest.approx(0.05 + 0.1 * 9, abs=0.05)


# -- over real sockets -----------------------------------------------------------------------------------------


@pytest.fixture
def leaking():
    with BridgeThread(speedup=SPEEDUP, params={**QUIET, "FS_LEAK_ENABLE": 2}, start_depth=3.0,
                      vehicle_faults=faults("leak@30s")) as b:
        yield b


def connect(b: BridgeThread) -> Gcs:
    g = Gcs(b.port, speedup=SPEEDUP)
    g.connect()
    return g


@pytest.mark.process
def test_udp_leak_with_fs_leak_enable_2_surfaces_an_armed_vehicle_and_it_rises(leaking):
    gcs = connect(leaking)
    try:
        assert gcs.command(mav.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == mav.MAV_RESULT_ACCEPTED
        text = gcs.recv("STATUSTEXT", WAIT, lambda m: m.text == "Leak Detected")
        assert text.severity == CRITICAL
        hb = gcs.recv("HEARTBEAT", WAIT, lambda m: m.custom_mode == MODES["SURFACE"])
        assert hb.system_status == mav.MAV_STATE_CRITICAL and hb.base_mode & 128
        start = gcs.recv("VFR_HUD").alt
        risen = gcs.recv("VFR_HUD", WAIT, lambda m: m.alt > start + 1.0)
        assert risen.alt > -2.0
    finally:
        gcs.close()


@pytest.mark.process
def test_udp_reboot_time_goes_back_after_the_silence_and_the_vehicle_boots_disarmed():
    with BridgeThread(speedup=SPEEDUP, params=QUIET, vehicle_faults=faults("reboot@25s")) as b:
        gcs = connect(b)
        try:
            assert gcs.set_param("SERVO2_FUNCTION", 52, mav.MAV_PARAM_TYPE_INT16).param_value == 52
            assert gcs.command(mav.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == mav.MAV_RESULT_ACCEPTED
            assert b.bridge.boot.reboots == 0                              # all that before the brown-out
            last = gcs.recv("ATTITUDE", WAIT, lambda m: m.time_boot_ms > 24500).time_boot_ms
            boot_hb = gcs.recv("HEARTBEAT", WAIT, lambda m: m.system_status == mav.MAV_STATE_BOOT)
            assert not boot_hb.base_mode & 128
            gcs.recv("STATUSTEXT", WAIT, lambda m: m.text == "ArduPilot Ready")
            attitude = gcs.recv("ATTITUDE")
            assert attitude.time_boot_ms < last and attitude.time_boot_ms >= 2000
            hb = gcs.recv("HEARTBEAT")
            assert hb.system_status == mav.MAV_STATE_STANDBY and hb.custom_mode == MODES["MANUAL"]
            assert not hb.base_mode & 128
            assert gcs.get_param("SERVO2_FUNCTION").param_value == 52
        finally:
            gcs.close()


@pytest.mark.process
def test_udp_preflight_reboot_command_is_acked_then_the_vehicle_reboots():
    with BridgeThread(speedup=SPEEDUP, params=QUIET) as b:
        gcs = connect(b)
        try:
            ack = gcs.command(mav.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN, 1)
            assert ack.result == mav.MAV_RESULT_ACCEPTED
            gcs.recv("STATUSTEXT", WAIT, lambda m: m.text == "ArduPilot Ready")
            assert b.bridge.boot.reboots == 1 and gcs.recv("ATTITUDE").time_boot_ms < 4000
        finally:
            gcs.close()


@pytest.mark.process
def test_tcp_clients_are_dropped_at_a_reboot():
    port = free_port(socket.SOCK_STREAM)
    config = BridgeConfig(endpoints=(f"tcpin:127.0.0.1:{port}",), speedup=SPEEDUP, params=QUIET,
                          vehicle_faults=faults("reboot@20s"))
    bridge = Bridge(config)
    bridge.start()
    try:
        sock = socket.create_connection(("127.0.0.1", port), timeout=WAIT)
        sock.settimeout(WAIT)
        received, deadline = len(sock.recv(65536)), time.monotonic() + WAIT
        assert received and bridge.boot.reboots == 0                    # connected before the brown-out
        while time.monotonic() < deadline:
            data = sock.recv(65536)
            if not data:
                break
            received += len(data)
        assert received > 0 and not data                                # it spoke, then closed the connection
        assert bridge.boot.reboots == 1
        sock.close()
    finally:
        bridge.stop()


@pytest.mark.process
def test_udp_navigation_lost_stops_local_position_ned():
    with BridgeThread(speedup=SPEEDUP, params=QUIET, vehicle_faults=faults("navigation-lost@1s")) as b:
        gcs = connect(b)
        try:
            report = gcs.recv("EKF_STATUS_REPORT", WAIT, lambda m: m.flags == 165)
            assert report.velocity_variance > 0.8
            gcs.drop_queued()
            seen = {m.get_type() for m in gcs.collect(1.0)}
            assert "GLOBAL_POSITION_INT" in seen and "LOCAL_POSITION_NED" not in seen
        finally:
            gcs.close()


@pytest.mark.process
def test_udp_depth_sensor_failure_texts_and_leaves_alt_hold_for_manual():
    with BridgeThread(speedup=SPEEDUP, params=QUIET, start_depth=2.0, vehicle_faults=faults("depth-sensor@20s")) as b:
        gcs = connect(b)
        try:
            assert gcs.command(mav.MAV_CMD_DO_SET_MODE, 1, MODES["ALT_HOLD"]).result == mav.MAV_RESULT_ACCEPTED
            text = gcs.recv("STATUSTEXT", WAIT, lambda m: m.text == "Depth sensor error!")
            assert text.severity == CRITICAL
            gcs.recv("HEARTBEAT", WAIT, lambda m: m.custom_mode == MODES["MANUAL"])
        finally:
            gcs.close()


# -- the command line ------------------------------------------------------------------------------------------


@pytest.mark.process
def test_cli_vehicle_faults_are_announced_and_malformed_ones_are_one_line_errors(tmp_path):
    r = subprocess.run([ROV_MAV, "sim-bridge", "--vehicle-faults", "thruster=9:dead@1s"], capture_output=True,
                       text=True, timeout=60)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert r.stderr.splitlines()[-1] == ("rov-mav sim-bridge: error: argument --vehicle-faults: thruster=9:dead@1s: "
                                         "expected thruster=N:KIND@TIME with N from 1 to 8, e.g. thruster=3:dead@60s")
    with BridgeProcess(tmp_path, "--vehicle-faults", "thruster=3:weak=0.5@1s,reboot@30s") as b:
        gcs = Gcs(b.port, speedup=SPEEDUP)
        try:
            gcs.connect()
            gcs.recv("STATUSTEXT", WAIT, lambda m: m.text == "ArduPilot Ready")
        finally:
            gcs.close()
    assert "vehicle faults thruster=3:weak=0.5@1s,reboot@30s" in b.output
    assert "sim-bridge: 1 reboot(s)" in b.output


@pytest.mark.process
def test_help_explains_the_vehicle_faults():
    r = subprocess.run([ROV_MAV, "sim-bridge", "--help"], capture_output=True, text=True, timeout=60)
    for words in ("--vehicle-faults", "navigation-lost@T[+D]", "FS_LEAK_ENABLE", "SURFACE", "ArduPilot Ready"):
        assert words in r.stdout


@pytest.mark.parametrize("navigation", ["ideal", "ugps"])
def test_a_navigation_reset_moves_the_estimate_not_the_vehicle(navigation):
    """navigation-reset=0.8/-0.6@2s: LOCAL_POSITION_NED steps by (0.8, -0.6) m against where it was going, the plant
    (the truth) does not move."""
    b, link = stepped("navigation-reset=0.8/-0.6@2s", start_depth=1.0, navigation=NAVIGATION_PRESETS[navigation])
    advance(b, 1.9)
    before, truth_before = b.estimate[0][:3].copy(), b.truth()[1][:3]
    advance(b, 0.2)
    after, truth_after = b.estimate[0][:3].copy(), b.truth()[1][:3]
    assert np.allclose(after - before, [0.8, -0.6, 0.0], atol=0.05)
    assert np.allclose(truth_after, truth_before, atol=0.01)
