"""Where the vehicle is now, asked once over the link without flying it: its estimate's local position and heading
(LOCAL_POSITION_NED, ATTITUDE), each requested with MAV_CMD_REQUEST_MESSAGE and taken from the streams ArduSub
sends anyway. Nothing on the vehicle changes; no heartbeat of ours is sent (a GCS failsafe is not armed by it)."""

from __future__ import annotations

import numpy as np

from rov_mav.flight.session.link import LinkError, Session, mavlink

CONNECT_WAIT = 30.0     # wall s for the vehicle's HEARTBEAT
ANSWER_WAIT = 10.0      # wall s for each message


def vehicle_pose(target: str, sysid: int = 255) -> np.ndarray:
    """(north, east, depth, heading) of the vehicle's estimate, m and rad; LinkError (one line) when it does not say."""
    session = Session.open(target, sysid=sysid)
    try:
        session.connect(CONNECT_WAIT)
        found = {}
        for name, msg_id in (("LOCAL_POSITION_NED", mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED),
                             ("ATTITUDE", mavlink.MAVLINK_MSG_ID_ATTITUDE)):
            session.request_message(msg_id)
            found[name] = session.wait(lambda m, name=name: m.get_type() == name, ANSWER_WAIT)
            if found[name] is None:
                raise LinkError(f"{target}: the vehicle sent no {name} within {ANSWER_WAIT:g} s: it has no position "
                                "estimate to fly a box around")
    finally:
        session.close()
    position, attitude = found["LOCAL_POSITION_NED"], found["ATTITUDE"]
    return np.array([position.x, position.y, position.z, attitude.yaw])
