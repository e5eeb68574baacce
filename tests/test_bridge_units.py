"""The bridge's pure layers on a simulated clock: parameters, RC input, mixer, ArduSub logic, scheduling, pacing,
the protocol's answers, battery and thruster physics. No sockets."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from rov_mav.model.thrusters import allocation_matrix, load_t200
from sim_bridge.autopilot import mixer
from sim_bridge.gcs import telemetry
from sim_bridge.autopilot.ardusub import MAV_RESULT_ACCEPTED, MAV_RESULT_FAILED, MODES, ArduSub
from sim_bridge.hardware.battery import Battery
from sim_bridge.config import BridgeConfig
from sim_bridge.autopilot.joystick import joystick_gain, rc_channels
from sim_bridge.gcs.missions import MissionProtocol
from sim_bridge.hardware.numeric import float_to_int, is_equal, is_zero, wrap
from sim_bridge.transport.pacing import LatenessHistogram, Pacer
from sim_bridge.autopilot.params import INT8, INT16, INT32, REAL32, Params, stored_value
from sim_bridge.hardware.physics import Physics
from sim_bridge.gcs.protocol import Protocol
from sim_bridge.autopilot.rc import RCInput
from sim_bridge.gcs.schedule import Scheduler, requested_interval_ms, stream_interval_ms
from sim_bridge.server import Bridge

GCS = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
STEP = 0.0025


def run(sub: ArduSub, t0: float, t1: float) -> float:
    """Main-loop passes from t0 to t1 at 400 Hz; returns t1."""
    for k in range(int(round((t1 - t0) / STEP))):
        sub.update(t0 + (k + 1) * STEP)
    return t1


def passthrough(params: Params) -> None:
    for n in range(1, 9):
        params.set(f"SERVO{n}_FUNCTION", 50 + n)


# -- parameters ------------------------------------------------------------------------------------------------


def test_param_names_follow_the_firmware():
    new, old = Params("4.7"), Params("4.5")
    assert new["MAV_GCS_SYSID"] == 255 and new["MAV_SYSID"] == 1 and new["MAV1_EXTRA1"] == 10
    assert "SYSID_MYGCS" not in new and "SR0_EXTRA1" not in new
    assert old["SYSID_MYGCS"] == 255 and old["SYSID_THISMAV"] == 1 and old["SR0_EXTRA1"] == 10
    assert "MAV_GCS_SYSID" not in old
    for p in (new, old):
        assert [p[f"SERVO{n}_FUNCTION"] for n in range(1, 9)] == list(range(33, 41))
        assert (p["RC_OVERRIDE_TIME"], p["FS_GCS_ENABLE"], p["FS_GCS_TIMEOUT"]) == (3.0, 2, 5.0)
        assert (p["FS_PILOT_INPUT"], p["FS_PILOT_TIMEOUT"]) == (2, 3.0)
        assert len({s.name for s in p.specs}) == len(p)
    with pytest.raises(ValueError):
        Params("4.1")


def test_4_7_names_and_units_of_the_position_controller_and_the_same_gains_flown():
    """AC_PosControl's, AC_WPNav's and AC_AttitudeControl's 4.7 names, in their 4.7 units (m, m/s, degrees; the
    vertical acceleration PID x 0.1, its IMAX x 0.001): a tuned 4.7 parameter file sets them, and GUIDED flies the
    same gains as 4.5's names and units give."""
    new, old = Params("4.7"), Params("4.5")
    assert (new["WP_SPD"], new["WP_SPD_UP"], new["WP_ACC"], new["ATC_ANGLE_MAX"]) == pytest.approx((1.0, 2.5, 2.5, 45))
    assert (new["PSC_NE_VEL_P"], new["PSC_NE_VEL_IMAX"], new["PSC_D_ACC_P"], new["PSC_D_ACC_IMAX"]) == \
        pytest.approx((6.0, 10.0, 0.05, 0.1))
    assert not {"WPNAV_SPEED", "PSC_VELXY_P", "PSC_ACCZ_P", "ANGLE_MAX"} & {s.name for s in new.specs}
    assert {"WPNAV_SPEED", "PSC_VELXY_P", "PSC_ACCZ_P", "ANGLE_MAX"} <= {s.name for s in old.specs}
    assert new.guided_gains() == pytest.approx(old.guided_gains())
    new.set("PSC_D_ACC_P", 0.08)
    new.set("ATC_ANGLE_MAX", 30)
    assert new.guided_gains()["PSC_ACCZ_P"] == pytest.approx(0.8) and new.guided_gains()["ANGLE_MAX"] == 3000


def test_param_set_stores_like_ardupilot():
    assert stored_value(51.4, INT16) == 51 and stored_value(-1.5, INT16) == -1 and stored_value(2.996, INT8) == 3
    assert stored_value(1000, INT8) == 127 and stored_value(-1e6, INT16) == -32768
    # measured on ArduSub 4.5.3 SITL (PARAM_SET of an INT16): float32 arithmetic, 0.01 away from zero, truncated
    assert [stored_value(v, INT16) for v in (0.99, 2.5, -2.5, 2.49, 1e9, -1e9)] == [1, 2, -2, 2, 32767, -32768]
    assert stored_value(3e9, INT32) == 2**31 - 1 and stored_value(2147483000, INT32) == 2147483008
    assert stored_value(0.123, REAL32) == float(np.float32(0.123)) != 0.123   # a float32, as on the wire
    p = Params()
    assert p.set("RC_OVERRIDE_TIME", 500.0) == 500.0          # documented range not enforced
    assert p.set("NO_SUCH_PARAM", 1.0) is None
    assert p.set("FS_GCS_TIMEOUT", math.nan) is None and p["FS_GCS_TIMEOUT"] == 5.0
    assert p.set("FS_GCS_TIMEOUT", 1e39) is None and p["FS_GCS_TIMEOUT"] == 5.0   # beyond float32: refused
    assert p.set("FS_GCS_ENABLE", 1e39) is None and p["FS_GCS_ENABLE"] == 2       # not a float32 either


# -- RC input --------------------------------------------------------------------------------------------------


def test_override_field_semantics():
    rc = RCInput()
    values = [1600, 65535, 0, 1400] + [65535] * 4 + [1700, 0, 65535, 65534] + [0] * 6
    rc.set_override(2, 1800, 0.0)
    rc.set_override(11, 1900, 0.0)
    rc.apply_message(values, 0.0)
    rc.update(0.1, 3.0)
    assert rc.radio_in[0] == 1600 and rc.radio_in[1] == 1500 and rc.radio_in[3] == 1400
    assert rc.radio_in[8] == 1700 and rc.radio_in[9] == 0 and rc.radio_in[10] == 0   # 4.7: never written: 0
    # channel 3 released (0 on 1-8) and channel 12 released (UINT16_MAX-1 on 9-18): they keep their last value
    assert rc.radio_in[2] == 1500 and rc.radio_in[11] == 0
    assert list(RCInput("4.5").radio_in[8:12]) == [1100, 1100, 1100, 0]   # 4.5: lights and video switch low


def test_overrides_expire_and_the_channel_keeps_its_last_value():
    rc = RCInput()
    rc.apply_message([1700] * 8 + [0] * 10, 1.0)
    rc.update(3.9, 3.0)
    assert np.all(rc.radio_in[:8] == 1700)
    rc.radio_in[:8] = 1234                      # anything written after expiry is no longer overwritten
    rc.update(4.1, 3.0)
    assert np.all(rc.radio_in[:8] == 1234)
    rc.update(4.1, -1)                          # -1: overrides never expire
    assert np.all(rc.radio_in[:8] == 1700)
    fresh = RCInput()
    fresh.apply_message([1700] * 8 + [0] * 10, 0.0)
    fresh.update(0.1, 0)                        # 0: overrides disabled
    assert np.all(fresh.radio_in[:8] == 1500)


def test_norm_input_scales_each_side():
    rc = RCInput()
    rc.radio_in[0] = 1300
    assert rc.norm_input(0, 1100, 1500, 1900) == pytest.approx(-0.5)
    rc.radio_in[0] = 2100
    assert rc.norm_input(0, 1100, 1500, 1900) == 1.0


# -- mixer -----------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("axis, dof, sign", [
    (0, 3, +1),    # roll right -> +K
    (1, 4, +1),    # pitch up -> +M
    (2, 5, +1),    # yaw right -> +N
    (3, 2, -1),    # throttle up -> -Z (rises)
    (4, 0, +1),    # forward -> +X
    (5, 1, +1),    # lateral right -> +Y
])
def test_mixer_axes_push_the_vehicle_the_right_way(vehicle, axis, dof, sign):
    axes = np.zeros(6)
    axes[axis] = 0.5
    out = mixer.mix(axes, np.ones(8))
    thrust = load_t200().thrust(mixer.to_pwm(out, 1100, 1900), 16.0)
    wrench = allocation_matrix(vehicle.thruster_positions, vehicle.thruster_directions) @ thrust
    assert sign * wrench[dof] > 1.0
    # the T200's weaker reverse leaves a net heave on the roll and pitch patterns
    others = np.delete(np.abs(wrench), [dof, 2] if dof in (3, 4) else [dof])
    assert others.max() < 0.2 * abs(wrench[dof]) + 0.5


def test_mixer_forward_pattern_normalisation_and_direction():
    pwm = mixer.to_pwm(mixer.mix([0, 0, 0, 0, 0.25, 0], np.ones(8)), 1100, 1900)
    assert list(pwm[:4]) == [1400, 1400, 1600, 1600] and np.all(pwm[4:] == 1500)
    saturated = mixer.mix([0, 0, 1, 0, 1, 1], np.ones(8))       # -3 on motor 2 before scaling
    assert saturated[1] == pytest.approx(-1.0) and saturated[0] == pytest.approx(1 / 3)
    reversed_ = mixer.mix([0, 0, 0, 0, 0.25, 0], np.array([-1.0] + [1.0] * 7))
    assert reversed_[0] == pytest.approx(0.25)


# -- ArduSub logic ---------------------------------------------------------------------------------------------


def test_boot_state_and_modes():
    sub = ArduSub(Params())
    assert (sub.mode, sub.armed, sub.base_mode(), sub.system_status()) == (19, False, 81, 3)
    assert sub.set_mode(MODES["POSHOLD"]) and sub.base_mode() == 89
    assert not sub.set_mode(MODES["AUTO"]) and not sub.set_mode(42) and sub.mode == MODES["POSHOLD"]
    assert sub.arm(True) == MAV_RESULT_ACCEPTED and sub.base_mode() == 89 + 128 and sub.system_status() == 4


def test_passthrough_ignores_arming_and_motor_functions_need_it():
    params = Params()
    sub = ArduSub(params)
    assert sub.rc_override(255, [1650] * 8 + [0] * 10, 0.0)
    sub.update(0.01)
    assert np.all(sub.servo_outputs()[:8] == 1500)              # motors: disarmed -> neutral
    assert sub.arm(True) == MAV_RESULT_FAILED                   # 4.7: the throttle (channel 3) is not at its trim
    sub.rc_override(255, [1650, 1650, 1500] + [1650] * 5 + [0] * 10, 0.01)
    sub.update(0.02)
    assert sub.arm(True) == MAV_RESULT_ACCEPTED
    sub.rc_override(255, [1650] * 8 + [0] * 10, 0.02)
    sub.update(0.03)
    assert np.all(sub.servo_outputs()[:8] != 1500)              # mixer of saturated pilot axes
    sub.arm(False)
    passthrough(params)
    assert np.all(sub.servo_outputs()[:8] == 1650)              # passthrough: disarmed, still driven
    assert np.all(sub.servo_outputs()[8:] == 0)


def test_wrong_sysid_override_is_ignored_entirely():
    params = Params()
    passthrough(params)
    sub = ArduSub(params)
    assert not sub.rc_override(42, [1700] * 8 + [0] * 10, 0.0)
    sub.update(0.01)
    assert np.all(sub.servo_outputs()[:8] == 1500)
    params.set("MAV_GCS_SYSID", 42)
    assert sub.rc_override(42, [1700] * 8 + [0] * 10, 0.02)


def test_pilot_input_failsafe_neutralises_1_to_6_and_keeps_7_8():
    params = Params()
    passthrough(params)
    sub = ArduSub(params)
    sub.rc_override(255, [1600] * 8 + [0] * 10, 0.0)
    sub.arm(True)
    run(sub, 0.0, 2.99)
    assert sub.armed and not sub.failsafes.pilot
    run(sub, 2.99, 3.01)
    assert sub.failsafes.pilot and not sub.armed and sub.system_status() == 5
    assert (2, "Lost manual control") in sub.texts
    out = sub.servo_outputs()
    assert np.all(out[:6] == 1500) and np.all(out[6:8] == 1600)
    run(sub, 3.01, 20.0)
    assert np.all(sub.servo_outputs()[6:8] == 1600)             # two thrusters keep running
    sub.rc_override(255, [1500] * 8 + [0] * 10, 20.0)
    sub.update(20.01)
    assert not sub.failsafes.pilot and sub.system_status() == 3


@pytest.mark.parametrize("override_time, after", [(3.0, [1520, 1480, 1500, 1500, 1500, 1500]),
                                                  (-1.0, [1600] * 6), (0.0, [1520, 1480, 1500, 1500, 1500, 1500])])
def test_pilot_input_failsafe_writes_the_trims_into_the_input_until_a_live_override_takes_it_back(override_time, after):
    """Sub::set_neutral_controls: channels 1-6 read their RCn_TRIM (not 1500) until the next RC read; an override
    that never times out (RC_OVERRIDE_TIME -1) comes back at once; with overrides off (0) the input stays at trim
    (here the overrides never reached it: it was at its boot value, 1500, then trim)."""
    params = Params()
    passthrough(params)
    params.set("RC1_TRIM", 1520)
    params.set("RC2_TRIM", 1480)
    params.set("RC_OVERRIDE_TIME", override_time)
    params.set("FS_PILOT_INPUT", 1)                             # warn only: the failsafe's effect on the input alone
    sub = ArduSub(params)
    sub.rc_override(255, [1600] * 8 + [0] * 10, 0.0)
    run(sub, 0.0, 2.99)
    assert sub.rc.radio_in[0] == (1500 if override_time == 0 else 1600)
    sub.update(3.0)
    assert sub.failsafes.pilot and list(sub.rc.radio_in[:2]) == [1520, 1480]
    run(sub, 3.0, 4.0)
    assert list(sub.rc.radio_in[:6]) == after
    assert list(sub.rc.radio_in[6:8]) == ([1500, 1500] if override_time == 0 else [1600, 1600])


def test_pilot_input_failsafe_fires_at_boot_and_only_once():
    sub = ArduSub(Params())
    run(sub, 0.0, 3.1)
    assert sub.failsafes.pilot and sub.texts.count((2, "Lost manual control")) == 1
    sub.arm(True)
    run(sub, 3.1, 10.0)
    assert sub.armed and sub.texts.count((2, "Lost manual control")) == 1


@pytest.mark.parametrize("action, armed, mode", [(1, True, 19), (2, False, 19), (3, True, 2), (4, True, 9)])
def test_gcs_failsafe_actions(action, armed, mode):
    params = Params()
    params.set("FS_PILOT_INPUT", 0)
    params.set("FS_GCS_ENABLE", action)
    sub = ArduSub(params)
    sub.arm(True)
    run(sub, 0.0, 40.0)
    assert sub.armed and not sub.failsafes.gcs                   # no GCS seen yet: no failsafe
    sub.gcs_heartbeat(255, 40.0)
    run(sub, 40.0, 44.9)
    assert sub.armed
    run(sub, 44.9, 45.4)                                        # 5 s timeout, checked at 3.3 Hz
    assert (sub.armed, sub.mode, sub.failsafes.gcs) == (armed, mode, True)
    assert (4, "MYGCS: 255, heartbeat lost") in sub.texts


@pytest.mark.parametrize("firmware", ["4.7", "4.5"])
def test_gcs_failsafe_says_nothing_in_the_first_30_s_then_every_30_s_and_4_7_says_when_it_clears(firmware):
    """Sub::failsafe_gcs_check: the warning's clock starts at 0 (boot), so a link lost 5 s after boot is acted on
    (disarm) at once but announced only past 30 s of uptime, then every 30 s; 4.7 says "GCS Failsafe Cleared"."""
    params = Params(firmware)
    params.set("FS_PILOT_INPUT", 0)
    sub = ArduSub(params)
    sub.arm(True)
    sub.gcs_heartbeat(255, 0.0)
    run(sub, 0.0, 29.9)
    assert not sub.armed and sub.failsafes.gcs and sub.texts == []
    run(sub, 29.9, 30.4)
    assert sub.texts == [(4, "MYGCS: 255, heartbeat lost")]
    run(sub, 30.4, 61.0)
    assert sub.texts.count((4, "MYGCS: 255, heartbeat lost")) == 2
    sub.gcs_heartbeat(255, 61.0)
    run(sub, 61.0, 62.0)
    cleared = [(4, "GCS Failsafe Cleared")] if firmware == "4.7" else []
    assert sub.texts[2:] == cleared and not sub.failsafes.gcs


def test_override_from_the_gcs_counts_as_heartbeat_and_others_do_not():
    params = Params()
    params.set("FS_PILOT_INPUT", 0)
    sub = ArduSub(params)
    sub.arm(True)
    sub.gcs_heartbeat(255, 0.0)
    for k in range(20):
        sub.gcs_heartbeat(7, k * 1.0)
        sub.rc_override(255, [1500] * 8 + [0] * 10, k * 1.0)
        run(sub, k * 1.0, k + 1.0)
    assert sub.armed
    run(sub, 20.0, 26.0)
    assert not sub.armed


# -- scheduling and pacing -------------------------------------------------------------------------------------


def count_due(scheduler: Scheduler, seconds: float) -> dict[str, int]:
    counts: dict[str, int] = {}
    for k in range(int(round(seconds / STEP))):
        for name in scheduler.due(k * STEP):
            counts[name] = counts.get(name, 0) + 1
    return counts


def test_default_rates_and_message_intervals():
    params = Params()
    names = ("HEARTBEAT", "ATTITUDE", "LOCAL_POSITION_NED", "SERVO_OUTPUT_RAW", "ATTITUDE_QUATERNION", "VFR_HUD")
    s = Scheduler(names, lambda g: params.stream_rate(0, g))
    counts = count_due(s, 10.0)
    # 3 Hz is every 333 ms (whole milliseconds, as ArduPilot): 31 in 10 s
    assert counts == {"HEARTBEAT": 10, "ATTITUDE": 100, "LOCAL_POSITION_NED": 31, "SERVO_OUTPUT_RAW": 20,
                      "VFR_HUD": 100}
    s.set_interval("ATTITUDE", 1e6 / 50, 0.0)
    s.set_interval("ATTITUDE_QUATERNION", 1e6 / 100, 0.0)
    s.set_interval("VFR_HUD", -1, 0.0)
    params.set("MAV1_POSITION", 8)
    s.refresh(0.0)
    counts = count_due(s, 10.0)
    assert (counts["ATTITUDE"], counts["ATTITUDE_QUATERNION"], counts["LOCAL_POSITION_NED"]) == (500, 1000, 80)
    assert "VFR_HUD" not in counts
    s.set_interval("ATTITUDE", 0, 0.0)                          # back to the stream rate
    assert s.intervals["ATTITUDE"] == pytest.approx(0.1)


def test_pacer_measures_lateness_and_reanchors_when_overloaded():
    now = [100.0]
    pacer = Pacer(0.01, speedup=10.0, clock=lambda: now[0])
    assert pacer.due(0.0) and not pacer.due(0.01)
    assert pacer.wait(0.01) == pytest.approx(0.001)
    now[0] += 0.0015
    assert pacer.due(0.01) and pacer.lateness.last == pytest.approx(0.0005)
    now[0] += 0.005                                             # a hiccup (0.05 s simulated): caught up
    assert all(pacer.due(0.01 * k) for k in range(2, 7)) and pacer.slips == 0
    now[0] += 0.015                                             # a stall past 0.1 s simulated: the world pauses
    assert pacer.due(0.07) and pacer.slips == 1 and pacer.wait(0.08) == pytest.approx(0.001)


def test_lateness_histogram_percentiles_match_numpy_within_a_bin():
    rng = np.random.default_rng(3)
    values = np.concatenate([rng.exponential(2e-4, 20000), rng.uniform(0.01, 0.05, 300), np.zeros(500)])
    histogram = LatenessHistogram()
    for v in values:
        histogram.add(float(v))
    assert histogram.count == values.size and histogram.max == values.max()
    assert histogram.total / histogram.count == pytest.approx(values.mean(), rel=1e-9)
    for q in (10, 50, 90, 99, 99.9):
        assert histogram.percentile(q) == pytest.approx(np.percentile(values, q), rel=0.03, abs=1e-7)
    assert histogram.counts.nbytes < 1e4                      # the same memory after a million steps as after one


# -- protocol --------------------------------------------------------------------------------------------------


@pytest.fixture
def protocol():
    params = Params()
    sub = ArduSub(params)
    scheduler = Scheduler(("HEARTBEAT", "ATTITUDE", "AUTOPILOT_VERSION"), lambda g: params.stream_rate(0, g))
    changed = []
    proto = Protocol(sub, params, snapshot=lambda: None, on_params_changed=changed.append,
                     missions=MissionProtocol(lambda: (0.0, 0.0, 0.0)))
    return proto, sub, params, scheduler, changed


def decode(msg):
    """A message as the vehicle's peer would see it (packed by a GCS-side encoder and parsed back)."""
    return mavlink.MAVLink(None).decode(bytearray(msg.pack(GCS)))


def test_protocol_commands_and_acks(protocol):
    proto, sub, params, scheduler, _ = protocol
    [(ack, to_all)] = proto.handle(decode(GCS.command_long_encode(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0)), 0,
                                   scheduler, 0.0)
    assert (ack.command, ack.result, ack.target_system, to_all) == (400, 0, 255, False) and sub.armed
    [(ack, _)] = proto.handle(decode(GCS.command_long_encode(1, 1, 400, 0, 3, 0, 0, 0, 0, 0, 0)), 0, scheduler, 0)
    assert ack.result == mavlink.MAV_RESULT_UNSUPPORTED
    [(ack, _)] = proto.handle(decode(GCS.set_mode_encode(1, 1, 2)), 0, scheduler, 0.0)
    assert (ack.command, ack.result, sub.mode) == (11, mavlink.MAV_RESULT_ACCEPTED, 2)
    [(ack, _)] = proto.handle(decode(GCS.command_long_encode(1, 1, 176, 0, 1, 3, 0, 0, 0, 0, 0)), 0, scheduler, 0)
    assert ack.result == mavlink.MAV_RESULT_FAILED and sub.mode == 2
    [(ack, _)] = proto.handle(decode(GCS.command_long_encode(1, 1, 176, 0, 0, 19, 0, 0, 0, 0, 0)), 0, scheduler, 0)
    assert ack.result == mavlink.MAV_RESULT_DENIED
    [(ack, _)] = proto.handle(decode(GCS.command_long_encode(1, 1, 511, 0, 9999, 1000, 0, 0, 0, 0, 0)), 0,
                              scheduler, 0)
    assert ack.result == mavlink.MAV_RESULT_DENIED
    [(ack, _)] = proto.handle(decode(GCS.command_long_encode(1, 1, 176, 0, math.nan, 19, 0, 0, 0, 0, 0)), 0,
                              scheduler, 0)
    assert ack.result == mavlink.MAV_RESULT_DENIED and sub.mode == 2


def test_protocol_parameters(protocol):
    proto, _, params, scheduler, changed = protocol
    banner, frame = proto.handle(decode(GCS.param_request_list_encode(1, 1)), 0, scheduler, 0.0)
    assert (banner[0].text, frame[0].text) == ("ArduSub V4.7.2 (00000000)", "Frame: VECTORED_6DOF")
    # streamed, PARAMS_PER_SECOND of vehicle time (one or two a 2.5 ms pass), in index order, to the asking link only
    passes = [proto.queued_params(0, k * 0.0025) for k in range(400)]
    replies = [r for sent in passes for r in sent]
    assert max(map(len, passes)) <= 2 and proto.queued_params(1, 1.0) == []
    assert [r.param_index for r in replies] == list(range(len(params)))
    assert {r.param_count for r in replies} == {len(params)}
    assert proto.queued_params(0, 2.0) == []                           # the list is done
    [(value, to_all)] = proto.handle(decode(GCS.param_set_encode(1, 1, b"SERVO1_FUNCTION", 51.2, 4)), 0,
                                     scheduler, 1.0)
    assert (value.param_id, value.param_value, value.param_index, to_all) == ("SERVO1_FUNCTION", 51, 65535, True)
    assert changed == [1.0]
    assert proto.handle(decode(GCS.param_set_encode(1, 1, b"NOPE", 1, 9)), 0, scheduler, 0.0) == []
    [(value, _)] = proto.handle(decode(GCS.param_request_read_encode(1, 1, b"", 1)), 0, scheduler, 0.0)
    assert value.param_id == "MAV_GCS_SYSID"
    proto.handle(decode(GCS.request_data_stream_encode(1, 1, 10, 25, 1)), 0, scheduler, 0.0)
    assert params["MAV1_EXTRA1"] == 25 and params["MAV2_EXTRA1"] == 10


def test_ftp_is_refused_so_clients_fall_back(protocol):
    proto, _, _, scheduler, _ = protocol
    request = bytes([7, 0, 0, 4, 5, 0, 0, 0, 0, 0, 0, 0]) + b"@PARAM".ljust(239, b"\0")
    [(reply, _)] = proto.handle(decode(GCS.file_transfer_protocol_encode(0, 1, 1, list(request))), 0, scheduler, 0)
    payload = bytes(reply.payload)
    assert (payload[0], payload[3], payload[4], payload[5], payload[12]) == (8, 129, 1, 4, 10)


# -- battery and thruster physics ------------------------------------------------------------------------------


def test_battery_sags_under_load_and_drains():
    b = Battery(16.8, 18.0)
    assert b.voltage == pytest.approx(16.8 - 0.03 * 0.5, abs=1e-3)
    b.step(100.0, 1.0)
    assert b.voltage < 16.8 - 3.0
    b.step(0.0, 3600 * 9.0 / 0.5)
    assert b.remaining == pytest.approx(0.5, abs=0.02) and b.voltage == pytest.approx(15.0, abs=0.1)


class _StillPlant:
    def __init__(self):
        self.taus = []

    def step(self, tau, h):
        self.taus.append(np.array(tau))


def test_thrust_lags_the_command_and_maps_to_the_wrench(vehicle):
    plant = _StillPlant()
    t200 = load_t200()
    physics = Physics(vehicle, plant, Battery(), t200, 0.001)
    pwm = np.array([1500] * 4 + [1700] * 4)
    for _ in range(20):                                        # one time constant (20 ms)
        physics.step(pwm)
    target = t200.thrust(1700, round(physics.battery.voltage, 2))
    assert physics.thrusts[4] / target == pytest.approx(1 - math.exp(-1), abs=0.02)
    for _ in range(200):
        physics.step(pwm)
    assert plant.taus[-1][2] == pytest.approx(4 * physics.thrusts[4]) and np.allclose(plant.taus[-1][[0, 1, 5]], 0)
    physics.step(np.zeros(8, dtype=int))                       # no pulse: the ESCs stop, not full reverse
    assert np.all(physics.thrusts >= 0)


# -- ArduSub's field limits ------------------------------------------------------------------------------------


def test_interval_limits_follow_ardupilot():
    assert [requested_interval_ms(us) for us in (0, -1, -5, 999, 20000, 2**31 - 1, -2**31)] == \
        [None, 0, 1, 1, 20, 60000, 1]
    assert [stream_interval_ms(r) for r in (0, 3, 10, 1000, 1001, -25536)] == [0, 333, 100, 1, 0, 60000]


def test_hostile_fields_are_clamped_or_refused(protocol):
    proto, sub, params, scheduler, _ = protocol
    proto.handle(decode(GCS.command_long_encode(1, 1, 511, 0, 30, 3.6e9, 0, 0, 0, 0, 0)), 0, scheduler, 0.0)
    [(interval, _), (ack, _)] = proto.handle(decode(GCS.command_long_encode(1, 1, 510, 0, 30, 0, 0, 0, 0, 0, 0)),
                                             0, scheduler, 0.0)
    assert (ack.result, interval.message_id, interval.interval_us) == (0, 30, 60_000_000)
    [(interval, _), (ack, _)] = proto.handle(decode(GCS.command_long_encode(1, 1, 510, 0, 70000, 0, 0, 0, 0, 0, 0)),
                                             0, scheduler, 0.0)
    assert (ack.result, interval.message_id, interval.interval_us) == (mavlink.MAV_RESULT_FAILED, 70000 - 65536, 0)
    proto.handle(decode(GCS.request_data_stream_encode(1, 1, 10, 40000, 1)), 6, scheduler, 0.0)
    assert params["MAV4_EXTRA1"] == -25536                      # uint16 read as int16; link 6 uses the last set
    proto.handle(decode(GCS.request_data_stream_encode(1, 1, 10, 7, 2)), 0, scheduler, 0.0)
    assert params["MAV1_EXTRA1"] == 10                          # start_stop 2: ignored
    assert proto.handle(decode(GCS.param_request_read_encode(1, 1, b"MAV1_EXTRA1", -7)), 0, scheduler, 0) == []


def test_c_conversions_as_on_arm():
    assert [float_to_int(v) for v in (3.6e9, -3.6e9, math.nan, math.inf, -7.9, 7.9)] == \
        [2**31 - 1, -2**31, 0, 2**31 - 1, -7, 7]
    assert [float_to_int(v, signed=False) for v in (-5.0, 5e9, math.nan, 275.5)] == [0, 2**32 - 1, 0, 275]
    assert float_to_int(40000.0, 16) == 40000 - 65536 and float_to_int(1e12, 16) == -1   # int32 first, low bits
    assert wrap(65534, 16) == -2 and wrap(-1, 16, signed=False) == 65535
    below, above = (float(np.nextafter(np.float32(1), np.float32(x))) for x in (0, 2))
    assert is_equal(below, 1.0) and not is_equal(above, 1.0) and not is_equal(math.nan, math.nan)
    assert is_zero(1e-10) and is_zero(-1e-10) and not is_zero(2e-7) and not is_zero(math.nan)


def test_commands_cast_their_parameters_as_ardusub_45_sitl(protocol):
    """Each answer here was measured on ArduSub 4.5.3 SITL (out-of-range casts excepted: those follow ARM)."""
    proto, sub, _, scheduler, _ = protocol

    def command(number, *params):
        replies = proto.handle(decode(GCS.command_long_encode(1, 1, number, 0, *params, *[0] * (7 - len(params)))),
                               0, scheduler, 0.0)
        return next(r for r, _ in replies if r.get_type() == "COMMAND_ACK").result

    below, above = (float(np.nextafter(np.float32(1), np.float32(x))) for x in (0, 2))
    assert command(400, above) == mavlink.MAV_RESULT_UNSUPPORTED and not sub.armed
    assert command(400, below) == mavlink.MAV_RESULT_ACCEPTED and sub.armed      # within float32's epsilon of 1
    assert command(400, 1e-10) == mavlink.MAV_RESULT_ACCEPTED and not sub.armed  # "zero"
    assert command(400, math.nan) == command(400, 2) == command(400, -1) == mavlink.MAV_RESULT_UNSUPPORTED
    assert command(176, 1.5, 275.7) == mavlink.MAV_RESULT_ACCEPTED and sub.mode == MODES["MANUAL"]  # 275 -> uint8 19
    assert command(176, 1, 2) == mavlink.MAV_RESULT_ACCEPTED and sub.mode == MODES["ALT_HOLD"]
    sub.texts.clear()
    assert command(176, 1, 99) == command(176, 1, 3) == mavlink.MAV_RESULT_FAILED and sub.mode == MODES["ALT_HOLD"]
    assert [text for _, text in sub.texts] == ["No such mode 99", "Flight mode change failed AUTO"]
    assert command(176, 0, 19) == command(176, 128, 2) == command(176, math.nan, 19) == mavlink.MAV_RESULT_DENIED
    assert command(176, 128, 1) == mavlink.MAV_RESULT_ACCEPTED and sub.safety_on
    assert not sub.servo_outputs().any()                                          # safety on: no pulses at all
    assert command(176, 128, 0) == mavlink.MAV_RESULT_ACCEPTED and sub.servo_outputs()[0] == 1500
    assert command(520, 0) == mavlink.MAV_RESULT_FAILED                           # capabilities need param1 = 1
    sub.texts.clear()
    assert command(511, 12345, 1e6) == mavlink.MAV_RESULT_DENIED
    assert sub.texts == [(6, "No ap_message for mavlink id (12345)")]
    assert command(511, math.nan, 5e5) == mavlink.MAV_RESULT_ACCEPTED             # NaN -> id 0: HEARTBEAT
    assert scheduler.intervals["HEARTBEAT"] == 0.5
    assert command(511, 0, math.nan) == mavlink.MAV_RESULT_ACCEPTED and scheduler.intervals["HEARTBEAT"] == 1.0
    assert command(5300, 0) == mavlink.MAV_RESULT_UNSUPPORTED                     # not in 4.5's command table


def test_requested_messages_follow_the_ack_and_sys_status_shows_the_safety():
    bridge = Bridge(BridgeConfig(endpoints=()))
    scheduler = Scheduler(("HEARTBEAT",), lambda g: 0)

    def request(number, param1):
        ack, reply = (r for r, _ in bridge.protocol.handle(
            decode(GCS.command_long_encode(1, 1, number, 0, param1, 0, 0, 0, 0, 0, 0)), 0, scheduler, 0.0))
        assert ack.result == mavlink.MAV_RESULT_ACCEPTED
        return reply

    assert request(520, 1.0).get_type() == request(512, mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION).get_type() == \
        "AUTOPILOT_VERSION"
    motors = mavlink.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS
    assert request(512, mavlink.MAVLINK_MSG_ID_SYS_STATUS).onboard_control_sensors_enabled & motors
    bridge.protocol.handle(decode(GCS.set_mode_encode(1, 128, 1)), 0, scheduler, 0.0)     # as 4.5.3 SITL shows it
    assert not request(512, mavlink.MAVLINK_MSG_ID_SYS_STATUS).onboard_control_sensors_enabled & motors


def test_attitude_angles_are_reported_within_pi():
    snap = Bridge(BridgeConfig(endpoints=())).snapshot()
    snap.eta = np.array([0.0, 0.0, 1.0, 0.1 + 2 * math.pi, -0.2, -4.08])       # the plant's yaw after turns
    m = telemetry.attitude(snap)
    assert (m.roll, m.pitch, m.yaw) == pytest.approx((0.1, -0.2, 2 * math.pi - 4.08))


def test_override_is_uint16_and_radio_in_int16_as_ardusub_45_sitl():
    """Measured on 4.5.3 SITL, armed in MANUAL: 40000, 32768 or 65534 on the throttle channel drove the vertical
    thrusters full down (int16 radio_in below trim), 32767 full up; RC_CHANNELS showed the override unchanged;
    channels 17 and 18 of RC_CHANNELS_OVERRIDE did nothing."""
    sub = ArduSub(Params())
    sub.arm(True)
    for value, vertical in ((40000, 1900), (32768, 1900), (65534, 1900), (32767, 1100), (1700, 1300)):
        sub.rc_override(255, [65535, 65535, value] + [65535] * 5 + [0] * 8 + [1700, 1800], 0.0)
        sub.update(0.0)
        assert list(sub.motor_pwm()[4:]) == [vertical] * 4 and sub.rc.radio_in[2] == value
    assert len(sub.rc.radio_in) == 16
    sub.rc.set_override(8, -5, 0.0)                              # an int16 parameter such as RC9_MIN, as uint16
    sub.update(0.0)
    assert sub.rc.radio_in[8] == 65531


def test_param_read_by_name_echoes_index_minus_one(protocol):
    proto, _, params, scheduler, _ = protocol
    [(value, _)] = proto.handle(decode(GCS.param_request_read_encode(1, 1, b"FS_GCS_ENABLE", -1)), 0, scheduler, 0)
    assert (value.param_id, value.param_index, value.param_count) == ("FS_GCS_ENABLE", 65535, len(params))


def test_joystick_maps_like_ardusub_45_sitl():
    gain = joystick_gain(0.5, 0.25, 1.0, 4)
    ch = lambda x=0, y=0, z=500, r=0, s=0, t=0: rc_channels(x, y, z, r, s, t, gain, 1.0, (1100, 1100))
    assert ch() == [1500] * 8 + [1100] * 3
    assert ch(400, -200, 700, 100) == [1500, 1500, 1580, 1520, 1580, 1460, 1500, 1500, 1100, 1100, 1100]
    assert ch(1000, -1000, 1000, -1000)[2:6] == [1700, 1300, 1700, 1300]
    assert ch(32767, -32768, -32768, 32767)[2:6] == [1100, 1900, 1900, 1100]
    assert ch(-1, 3, 499, -6)[2:6] == [1499, 1498, 1499, 1500]   # truncation toward zero, as measured
    assert ch(s=100, t=-200)[:2] == [1600, 1300]
    assert ch(s=32767)[0] == 1100                               # int16 wrap before the clamp, as in C++
    assert joystick_gain(0.05, 0.25, 1.0, 4) == pytest.approx(0.5) and joystick_gain(2, 0.25, 1.0, 1) == 1.0


@pytest.mark.parametrize("firmware, lights", [("4.7", [0, 0, 0]), ("4.5", [1100, 1100, 1100])])
def test_manual_control_only_from_the_gcs_to_this_vehicle(firmware, lights):
    """4.5 overrides channels 1-11 (lights and video switch low); 4.7 only 1-8, its lights are servo functions."""
    params = Params(firmware)
    sub = ArduSub(params)
    axes = (200, 0, 500, 0, 0, 0)
    assert not sub.manual_control(254, 1, axes, 0.0) and not sub.manual_control(255, 0, axes, 0.0)
    sub.update(0.1)
    assert sub.rc.radio_in[4] == 1500
    sub.rc.radio_in[8:11] = 1234                # what a station's override left there
    assert sub.manual_control(255, 1, axes, 1.0)
    sub.update(1.0)
    assert list(sub.rc.radio_in[:8]) == [1500, 1500, 1500, 1500, 1540, 1500, 1500, 1500]
    assert list(sub.rc.radio_in[8:11]) == (lights if firmware == "4.5" else [1234] * 3)
    assert not sub.failsafes.pilot
    params.set("FS_PILOT_INPUT", 0)
    sub.rc.radio_in[4] = 1234                   # still overridden just before RC_OVERRIDE_TIME (3 s) has passed,
    sub.update(3.9)
    assert sub.rc.radio_in[4] == 1540
    sub.rc.radio_in[4] = 1234                   # and no longer after it
    sub.update(4.1)
    assert sub.rc.radio_in[4] == 1234


def test_invalid_motor_pwm_range_falls_back_to_rc3_and_outputs_fit_uint16():
    params = Params()
    sub = ArduSub(params)
    sub.arm(True)
    sub.rc.set_override(2, 1900, 0.0)
    params.set("MOT_PWM_MIN", 1950)                              # min >= max: AP_Motors uses RC3_MIN..MAX
    sub.update(0.0)
    assert set(sub.motor_pwm()) == {1100, 1500}                  # full throttle on the verticals
    params.set("RC3_MAX", -500)
    params.set("SERVO9_FUNCTION", 59)
    sub.rc.set_override(8, 65534, 0.0)
    sub.update(0.0)
    out = sub.servo_outputs()
    assert out.min() >= 0 and out.max() <= 65535 and out[8] == 65534


def test_the_packs_voltage_follows_its_discharge_table_and_falls_with_current():
    """The open-circuit voltage is the 4S table's, linear between its points (the same as numpy's interp), held at
    its ends; the terminal voltage loses INTERNAL_RESISTANCE x the current drawn."""
    from sim_bridge.hardware.battery import _OCV, _SOC, INTERNAL_RESISTANCE, _open_circuit

    for soc in np.r_[np.linspace(-0.1, 1.1, 241), _SOC]:
        assert _open_circuit(soc) == pytest.approx(np.interp(soc, _SOC, _OCV), abs=1e-12)
    pack = Battery()
    pack.step(20.0, 360.0)                         # 20 A (plus the electronics' 0.5 A) for 6 minutes
    assert pack.remaining == pytest.approx(1.0 - 20.5 * 0.1 / 18.0)
    assert pack.voltage == pytest.approx(np.interp(pack.remaining, _SOC, _OCV) - INTERNAL_RESISTANCE * 20.5)
