"""The built-in vehicle's MAVLink routing between its links, against ArduPilot's rules
(`MAVLink_routing::check_and_forward`): heartbeats reach every other link, what is addressed to the vehicle stays
there, broadcasts go where some system was seen, a message for another system goes where that system is."""

from __future__ import annotations

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sim_bridge.gcs.routing import Router, targets

LINKS = [0, 1, 2]


def sent(sysid: int, compid: int, build):
    """A message as it arrives: packed by a station `sysid`/`compid`, parsed back."""
    station = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=compid)
    buf = build(station).pack(station)
    return mavlink.MAVLink(None).parse_buffer(buf)[0]


def heartbeat(sysid: int, compid: int = 190):
    return sent(sysid, compid, lambda m: m.heartbeat_encode(6, 8, 0, 0, 0))


def manual_control(sysid: int, target: int = 1):
    return sent(sysid, 190, lambda m: m.manual_control_encode(target, 600, 0, 500, 0, 0))


def override(sysid: int, target: int = 1):
    return sent(sysid, 190, lambda m: m.rc_channels_override_encode(target, 1, *([1500] * 8), *([0] * 10)))


def arm(sysid: int, target: int = 1):
    return sent(sysid, 190, lambda m: m.command_long_encode(target, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0))


def gps_input(sysid: int = 1, compid: int = 220):
    return sent(sysid, compid, lambda m: m.gps_input_encode(0, 0, 0, 0, 0, 3, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 10))


def test_the_targets_are_read_as_the_generator_marks_them():
    assert targets(manual_control(255, target=1)) == (1, -1)           # MANUAL_CONTROL's `target` is a system
    assert targets(arm(255, target=3)) == (3, 1)
    assert targets(heartbeat(255)) == (-1, -1)


def test_a_stations_heartbeat_reaches_every_other_link_but_not_where_it_came_from():
    router = Router(1)
    assert router.route(1, heartbeat(255), LINKS) == (True, [0, 2])
    router.route(2, heartbeat(255), LINKS)                               # the same station seen on link 2 too
    assert router.route(1, heartbeat(255), LINKS) == (True, [0])


def test_what_is_addressed_to_the_vehicle_is_handled_and_never_forwarded():
    router = Router(1)
    for link in LINKS:                                                   # a station on every link
        router.route(link, heartbeat(200 + link), LINKS)
    for msg in (manual_control(255), override(255), arm(255)):
        assert router.route(1, msg, LINKS) == (True, []), msg.get_type()


def test_a_broadcast_goes_only_to_links_where_a_system_was_seen():
    router = Router(1)
    router.route(2, heartbeat(200), LINKS)
    assert router.route(0, gps_input(), LINKS) == (True, [2])            # link 1: nobody seen there yet
    router.route(1, heartbeat(255), LINKS)
    assert router.route(0, gps_input(), LINKS) == (True, [1, 2])


def test_a_message_for_another_system_goes_where_it_was_seen_and_is_not_handled():
    router = Router(1)
    router.route(2, heartbeat(7, 1), LINKS)
    handled, forward = router.route(0, arm(255, target=7), LINKS)
    assert (handled, forward) == (False, [2])
    assert router.route(0, arm(255, target=9), LINKS) == (False, [])    # nobody knows system 9: dropped


def test_a_private_link_learns_nothing_forwards_nothing_and_gets_no_heartbeats():
    router = Router(1)
    private = {2}
    assert router.route(2, heartbeat(200), LINKS, private) == (True, [])
    assert router.route(1, heartbeat(255), LINKS, private) == (True, [0])
    assert router.route(0, gps_input(), LINKS, private) == (True, [1])


def test_a_command_for_a_component_nobody_has_seen_is_handled_here_and_forwarded_once_it_is_seen():
    """Rule 1e: the vehicle's sysid, a component no link has shown: the autopilot takes it."""
    router = Router(1)
    command = arm(255, target=1)
    command_5 = sent(255, 190, lambda m: m.command_long_encode(1, 5, 400, 0, 1, 0, 0, 0, 0, 0, 0))
    assert router.route(0, command_5, LINKS) == (True, [])
    router.route(2, heartbeat(1, 5), LINKS)                              # a camera, component 5, on link 2
    assert router.route(0, command_5, LINKS) == (False, [2])
    assert router.route(0, command, LINKS) == (True, [])


def test_the_vehicles_own_messages_looped_back_are_handled_but_not_learnt():
    router = Router(1)
    assert router.route(0, sent(1, 1, lambda m: m.heartbeat_encode(12, 3, 0, 0, 0)), LINKS) == (True, [])
    assert not router.routes
