"""The mission stored on the vehicle, downloaded over the MAVLink mission protocol and read as a plan's items are.

Download (the ground station's side of libraries/GCS_MAVLink/MissionItemProtocol.cpp): MISSION_REQUEST_LIST ->
MISSION_COUNT (items including home, item 0) -> MISSION_REQUEST_INT for each -> MISSION_ITEM_INT, then our
MISSION_ACK. Each request is sent again when its answer is late; a MISSION_ACK with an error (e.g. DENIED while
another station uploads) ends the download. Nothing on the vehicle changes.

What the items mean is `rov_mav.mission.mission_items` (as for a QGroundControl plan), with two differences that
come from ArduSub: home (item 0, always the vehicle's current home) is the default origin, and a waypoint's yaw is
not used, because AP_Mission stores only the hold time of a NAV_WAYPOINT (`mavlink_int_to_mission_cmd`) and hands
back 0 for its param2-4. The legs' speed is the vehicle's WP_SPD (m/s; WPNAV_SPEED in cm/s before 4.7, PR #32147),
as ArduSub's AUTO flies them.
"""

from __future__ import annotations

from rov_mav import config
from rov_mav.flight.session.link import RETRY_BUDGET, LinkError, Session, mavlink
from rov_mav.mission.mission_items import MissionItem, Planned, PlanOptions, build_mission
from rov_mav.mission.missions import Mission

MISSION_TYPE = mavlink.MAV_MISSION_TYPE_MISSION
SPEED_PARAMS = {"WP_SPD": 1.0, "WPNAV_SPEED": 0.01}    # m/s per unit: 4.7 and later, before 4.7


def download(session: Session) -> list[MissionItem]:
    """Every item of the vehicle's mission, home (item 0) first; LinkError if the vehicle does not hand it over."""
    count = _ask(session, lambda: _send(session, "mission_request_list", MISSION_TYPE),
                 lambda m: m.get_type() == "MISSION_COUNT" and m.mission_type == MISSION_TYPE, "MISSION_COUNT").count
    items = []
    for seq in range(count):
        item = _ask(session, lambda s=seq: _send(session, "mission_request_int", s, MISSION_TYPE),
                    lambda m, s=seq: m.get_type() == "MISSION_ITEM_INT" and m.seq == s
                    and m.mission_type == MISSION_TYPE, f"item {seq} of {count}")
        items.append(MissionItem(f"vehicle item {seq}", item.command, item.frame,
                                 (item.param1, item.param2, item.param3, item.param4, item.x / 1e7, item.y / 1e7,
                                  item.z)))
    _send(session, "mission_ack", mavlink.MAV_MISSION_ACCEPTED, MISSION_TYPE)
    return items


def vehicle_mission(session: Session, options: PlanOptions = PlanOptions()) -> Mission:
    """The vehicle's mission as a Mission (connect the session first); LinkError if it cannot be downloaded,
    ConfigError if it is empty or holds anything we would not fly."""
    items = download(session)
    source = f"the vehicle's mission ({session.target})"
    if len(items) < 2:
        raise config.ConfigError(f"{source}: empty: upload a mission to the vehicle first (QGroundControl's Plan "
                                 f"view, MAVProxy's `wp load FILE`)")
    home = items[0].params[4:6]
    found = session.get_params(list(SPEED_PARAMS), any_of=True)
    name = next(iter(found), "WP_SPD")
    planned = Planned(name="vehicle_mission", source=source, home=home if any(home) else None,
                      speed=found[name][0] * SPEED_PARAMS[name] if found else None,
                      speed_origin=f"the vehicle's {name}",
                      items=items[1:], use_yaw=False)
    return build_mission(planned, options)


def _ask(session: Session, send, predicate, what: str):
    """Send, wait for the answer matching `predicate`, send again when it is late (the session's resend schedule);
    LinkError when none comes within its budget or on an error MISSION_ACK."""
    def answer(m):
        return predicate(m) or (m.get_type() == "MISSION_ACK" and m.mission_type == MISSION_TYPE
                                and m.type != mavlink.MAV_MISSION_ACCEPTED)

    reply = session.ask(send, answer)
    if reply is None:
        raise LinkError(f"mission download from {session.target}: no {what} within {RETRY_BUDGET:g} s of requests")
    if reply.get_type() == "MISSION_ACK":
        entry = mavlink.enums["MAV_MISSION_RESULT"].get(reply.type)
        result = entry.name.removeprefix("MAV_MISSION_") if entry else str(reply.type)
        raise LinkError(f"the vehicle refused the mission download: {result}"
                        + (" (another station is uploading a mission)" if result == "DENIED" else ""))
    return reply


def _send(session: Session, name: str, *fields) -> None:
    vehicle = session.vehicle
    try:
        getattr(session.conn.mav, f"{name}_send")(vehicle.sysid, vehicle.compid, *fields)
    except OSError as exc:
        raise LinkError(f"mission download from {session.target}: {exc.strerror or exc}") from None
