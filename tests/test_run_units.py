"""The runner's pieces without a link: the vehicle clock, the state decoder, the lead-in, the actuation limits."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rov_mav.flight.thrusters.actuation import Actuation
from rov_mav.flight.record.history import History
from rov_mav.flight.session.link import mavlink
from rov_mav.flight.session.stations import ECHO_MEMORY, OverrideEcho, Sighting, StationWatch, judge
from rov_mav.flight.session.vehicle_clock import VehicleClock
from rov_mav.flight.session.vehicle_events import EXIT_REBOOT, RebootWatch
from rov_mav.flight.state.vehicle_state import StateDecoder
from rov_mav.mission.approach import approach
from rov_mav.model import dynamics
from rov_mav.model.thrusters import load_t200


def test_the_vehicle_clock_learns_the_speedup_and_extrapolates():
    clock = VehicleClock()
    for k in range(31):                       # a vehicle at 10x, stamps every 0.1 wall s
        clock.observe(100.0 + k * 1.0, wall=k * 0.1)
    assert clock.rate == pytest.approx(10.0)
    assert clock.now(wall=3.5) == pytest.approx(135.0)       # 0.5 wall s of silence = 5 vehicle s
    assert clock.wall_seconds(2.0) == pytest.approx(0.2)
    clock.observe(129.5, wall=3.6)                            # a late, reordered stamp changes nothing
    assert clock.last_vehicle == 130.0


def test_the_state_is_in_the_body_frame_and_on_the_vehicle_clock():
    decoder = StateDecoder()
    yaw = math.pi / 2                                          # facing east
    att = mavlink.MAVLink_attitude_message(2000, 0.0, 0.0, yaw, 0.01, 0.02, 0.03)
    pos = mavlink.MAVLink_local_position_ned_message(2010, 1.0, 2.0, 3.0, 0.0, 0.5, 0.1)   # moving east
    assert not decoder.update(att)
    assert decoder.update(pos)
    state = decoder.state(received=0.0)
    assert state.t == pytest.approx(2.010)
    # the attitude, 10 ms older than the position, brought forward by its rates (level: T(Theta) = I)
    np.testing.assert_allclose(state.eta, [1.0, 2.0, 3.0, 0.0001, 0.0002, yaw + 0.0003], rtol=0, atol=1e-12)
    body = dynamics.rotation(state.eta).T @ [0.0, 0.5, 0.1]                    # surge forward, at that attitude
    np.testing.assert_allclose(state.nu, [*body, 0.01, 0.02, 0.03], atol=1e-12)
    np.testing.assert_allclose(body, [0.5, 0.0, 0.1], atol=3e-4)
    assert not decoder.update(pos)                             # a pair needs both messages again


def test_a_lost_attitude_costs_one_sample_not_every_later_pairing():
    """Streams at 50 Hz, ATTITUDE then LOCAL_POSITION_NED each period with the same stamp; one ATTITUDE lost, one
    position duplicated, then a reboot: every completed state pairs messages of one period."""
    decoder = StateDecoder()

    def period(ms, x, attitude=True, position=True):
        msgs = [mavlink.MAVLink_attitude_message(ms, 0.0, 0.0, x, 0.0, 0.0, 0.0)] if attitude else []
        msgs += [mavlink.MAVLink_local_position_ned_message(ms, x, 0.0, 0.0, 0.0, 0.0, 0.0)] if position else []
        return msgs

    stream = []
    for k in range(20):
        stream += period(1000 + 20 * k, float(k), attitude=k != 5)
        if k == 9:
            stream += period(1000 + 20 * k, float(k), attitude=False)       # a duplicated position
    stream += period(40, 100.0) + period(60, 101.0)                         # rebooted: a new clock
    states = []
    for msg in stream:
        if decoder.update(msg):
            states.append(decoder.state(received=0.0))
    assert [s.eta[0] for s in states] == [k for k in range(20) if k != 5] + [100.0, 101.0]
    assert all(s.eta[0] == s.eta[5] for s in states)                         # position and attitude of one period


def test_a_run_meets_a_reboot_once_its_clock_has_seen_it_and_reads_mission_time_across_it():
    """A reboot before the run is not its own; one during it ends it (or names the exit when first seen while
    stopping), and a time after it reads as if the vehicle's clock had run on."""
    clock = VehicleClock()
    clock.observe(500.0, wall=0.0)
    clock.observe(2.0, wall=0.1)                               # an earlier reboot: not this run's
    watch = RebootWatch(clock)
    boot = mavlink.MAVLink_heartbeat_message(12, 3, 0, 0, mavlink.MAV_STATE_ACTIVE, 3)
    for t in np.arange(2.0, 60.0, 0.5):
        clock.observe(t, wall=t)
    assert watch.while_flying(boot, "HEARTBEAT", 60.0) is None
    assert watch.while_stopping(0, "mission complete") == (0, "mission complete")
    assert watch.time_lost(59.5) == 0.0
    boot.system_status = mavlink.MAV_STATE_BOOT                # it says it is booting before its clock is seen back
    assert "rebooted" in watch.while_flying(boot, "HEARTBEAT", 60.0)
    clock.observe(3.0, wall=61.0)                              # its clock went back from 59.5 s to 3 s
    boot.system_status = mavlink.MAV_STATE_ACTIVE
    assert "from 59.5 s to 3.0 s" in watch.while_flying(boot, "HEARTBEAT", 61.0)
    assert watch.time_lost(3.0) == pytest.approx(56.5)         # after it: as if the clock had run on
    assert watch.time_lost(59.4) == 0.0                        # a late time from before it
    code, reason = watch.while_stopping(1, "the link was lost")
    assert code == EXIT_REBOOT and reason.endswith("first seen as: the link was lost")
    assert watch.while_stopping(EXIT_REBOOT, "named") == (EXIT_REBOOT, "named")


def test_a_state_read_after_its_batch_is_the_completed_pair_not_the_next_periods_half():
    """The runner decodes once per batch it reads: a batch that completes period k and then brings period k+1's
    ATTITUDE still gives period k's sample (position and attitude of one stamp)."""
    decoder = StateDecoder()
    stream = []
    for k in range(10):
        stream += [mavlink.MAVLink_attitude_message(1000 + 20 * k, 0.0, 0.0, float(k), 0.0, 0.0, 0.0),
                   mavlink.MAVLink_local_position_ned_message(1000 + 20 * k, float(k), 0.0, 0.0, 0.0, 0.0, 0.0)]
    states = []
    for start in range(0, len(stream), 3):                                   # batches of three messages
        if any([decoder.update(msg) for msg in stream[start:start + 3]]):
            states.append(decoder.state(received=0.0))
    assert len(states) >= 6
    assert all(s.eta[0] == s.eta[5] and s.t == pytest.approx(1.0 + 0.02 * s.eta[0]) for s in states)


def test_the_lead_in_reaches_the_start_pose_smoothly_or_is_skipped():
    start = np.array([0.0, 0.0, 1.0, 0.0, 0.0, 0.0])
    assert approach(start + 0.01, start, 0.2) is None
    eta = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 3.0])
    lead = approach(eta, start, 0.2)
    np.testing.assert_allclose(lead.reference(0.0)[:6], eta)
    end = lead.reference(lead.duration)
    np.testing.assert_allclose(end[:3], start[:3])
    assert math.isclose(math.cos(end[5]), 1.0) and not end[6:].any()
    assert lead.duration >= 3.0 / 0.2                          # turns no faster than 0.2 rad/s


def test_actuation_caps_every_thruster_and_uses_the_battery_voltage(vehicle):
    act = Actuation(vehicle, max_thrust=20.0, voltage=16.0)
    thrusts, pwm, info = act.command(np.array([500.0, 0, 0, 0, 0, 0]))   # far beyond the vehicle
    assert np.all(np.abs(thrusts) <= 20.0 + 1e-9) and info.saturated
    np.testing.assert_allclose(pwm, np.round(load_t200().pwm(thrusts, 16.0)))
    _, pwm_16v, _ = act.command(np.array([10.0, 0, 0, 0, 0, 0]))
    act.set_voltage(12.0)
    _, pwm_12v, _ = act.command(np.array([10.0, 0, 0, 0, 0, 0]))
    assert np.any(np.abs(pwm_12v - 1500) > np.abs(pwm_16v - 1500))    # a weaker battery needs more PWM


def test_the_thrust_cap_holds_in_pwm_at_the_highest_voltage_seen(vehicle):
    """A PWM computed at a sagged voltage must not exceed the cap once the battery recovers."""
    t200 = load_t200()
    act = Actuation(vehicle, max_thrust=40.0, voltage=16.8)
    act.set_voltage(14.0)                                               # sagged under load
    thrusts, pwm, _ = act.command(np.array([500.0, 0, 300.0, 0, 0, 0]))
    assert np.all(np.abs(t200.thrust(pwm, 16.8)) <= 40.0 + 0.3)         # what the recovered battery would push
    assert not act.beyond_cap(pwm).any()
    assert act.beyond_cap(np.array([1500, 1500, 1900, 1500, 1500, 1500, 1500, 1500])).tolist() == \
        [False, False, True, False, False, False, False, False]


def test_reversed_thrusters_get_mirrored_pwm(vehicle):
    """Passthrough bypasses MOT_n_DIRECTION: a thruster with direction -1 is sent 3000 - PWM."""
    act = Actuation(vehicle, max_thrust=40.0, voltage=16.0)
    tau = np.array([20.0, 5.0, -10.0, 0, 0, 1.0])
    _, straight, _ = act.command(tau)
    act.set_directions(np.array([1, -1, 1, 1, 1, 1, -1, 1]))
    act.reset()                                                # the same tick again: nothing carried
    _, mirrored, _ = act.command(tau)
    np.testing.assert_array_equal(mirrored[[0, 2, 3, 4, 5, 7]], straight[[0, 2, 3, 4, 5, 7]])
    np.testing.assert_array_equal(mirrored[[1, 6]], 3000 - straight[[1, 6]])
    assert not act.beyond_cap(mirrored).any()


def test_history_keeps_every_row_across_growth():
    history = History(capacity=2, t=1, eta=6)
    rows = np.random.default_rng(0).normal(size=(37, 7))
    for row in rows:
        history.append(t=row[0], eta=row[1:])
    assert history.column("t").shape == (37,) and history.column("eta").shape == (37, 6)
    np.testing.assert_array_equal(history.column("t"), rows[:, 0])
    np.testing.assert_array_equal(history.column("eta"), rows[:, 1:])
    assert History(t=1, eta=6).column("eta").shape == (0, 6)


def test_override_echo_knows_its_own_commands_by_value_and_a_strangers_at_once():
    echo = OverrideEcho()
    ours = [[1500 + k, 1500 - k, 1510, 1490, 1500, 1500, 1520 + k, 1480] for k in range(300)]
    upper = [0] * 8                                                         # RC 9-16 as found
    for pwm in ours:
        echo.sent_now(pwm)
    assert not echo.rc(ours[0] + upper) and not echo.rc(ours[-1] + upper)   # however late it arrives
    stranger = [1500, 1500, 1500, 1500, 1620, 1500, 1500, 1500]            # a pilot's joystick, x = 600
    assert echo.servo(stranger)                                        # interleaved with ours: one shows it
    echo = OverrideEcho()
    echo.sent_now(ours[5])
    assert not echo.rc([v + 1 for v in ours[5]] + upper) and not echo.rc([v - 1 for v in ours[5]] + upper)
    assert not echo.servo(ours[5]) and echo.rc(ours[5] + [1100] + upper[1:])   # RC 9: someone's button
    echo = OverrideEcho()
    echo.sent_now(ours[-1])
    for _ in range(ECHO_MEMORY):
        echo.sent_now([1600] * 8)
    assert echo.servo(ours[-1])                                        # forgotten after ECHO_MEMORY sends


def test_streams_half_a_period_apart_keep_their_pairing_after_a_loss():
    """ATTITUDE at k*20 ms, LOCAL_POSITION_NED 10 ms later: each position pairs with the attitude before it. After a
    lost ATTITUDE (or a lost position) the pairing stays (attitude k, position k), not (position k, attitude k+1)
    for the rest of the run, which would date every later position half a period early."""
    for lost in ("ATTITUDE", "LOCAL_POSITION_NED"):
        decoder = StateDecoder()
        states = []
        for k in range(30):
            msgs = [mavlink.MAVLink_attitude_message(1000 + 20 * k, 0.0, 0.0, float(k), 0.0, 0.0, 0.0),
                    mavlink.MAVLink_local_position_ned_message(1010 + 20 * k, float(k), 0.0, 0.0, 0.0, 0.0, 0.0)]
            for msg in msgs:
                if k == 12 and msg.get_type() == lost:
                    continue
                if decoder.update(msg):
                    states.append(decoder.state(received=0.0))
        assert [s.eta[0] for s in states] == [k for k in range(30) if k != 12], lost
        assert all(s.eta[0] == s.eta[5] and s.t == pytest.approx(1.010 + 0.02 * s.eta[0]) for s in states), lost


def _from(sysid: int, msg):
    """`msg` as it arrives from `sysid` (packed and parsed: the source is in the header)."""
    mav = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=190)
    return mav.decode(bytearray(msg.pack(mav)))


def test_a_station_sending_motor_tests_drives_the_thrusters():
    """ArduSub takes MAV_CMD_DO_MOTOR_TEST from any sysid: a station sending it to the vehicle (or to all) is driving
    it - the vehicle is refused before a run, taken from the run while flying; one aimed elsewhere is not."""
    watch = StationWatch(vehicle_sysid=1)
    watch.observe(_from(42, mavlink.MAVLink_command_long_message(7, 1, 209, 0, 0, 1, 1600, 0.5, 0, 2, 0)), 4.0)
    assert watch.overriding(0.0) == []
    watch.observe(_from(42, mavlink.MAVLink_command_long_message(1, 1, 209, 0, 0, 1, 1600, 0.5, 0, 2, 0)), 5.0)
    watch.observe(_from(43, mavlink.MAVLink_command_int_message(0, 1, 0, 209, 0, 0, 3, 1, 1500, 0, 0, 2, 0)), 6.0)
    assert [s.sysid for s in watch.overriding(5.0)] == [42, 43] and watch.overriding(6.5) == []
    assert "MAV_CMD_DO_MOTOR_TEST x 1" in watch.overriding(5.0)[0].describe()
    verdict = judge(Sighting(since=0.0, armed=False, passthrough=[]), watch, force=False)
    assert verdict.refusal is not None and "another station is driving it: station sysid 42" in verdict.refusal
