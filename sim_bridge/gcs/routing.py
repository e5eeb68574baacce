"""MAVLink routing between the vehicle's links, as ArduPilot does it (`libraries/GCS_MAVLink/MAVLink_routing.cpp`).

`MAVLink_routing::check_and_forward`, called for every message a link receives before it is handled
(`GCS_MAVLINK::packetReceived`):
- a message from the vehicle's own sysid and component (a loop-back) is handled, never learnt nor forwarded;
- every other sender's (sysid, component) is learnt on the link it arrived on (`learn_route`; sysid 0 is not);
- RADIO, RADIO_STATUS and ADSB_VEHICLE are handled here and never forwarded;
- a HEARTBEAT is handled and forwarded to every other link except those where its sender is known to be
  (`handle_heartbeat`): so each station learns who else is on the vehicle;
- a message addressed to the vehicle (target_system its sysid, target_component its own or absent; MANUAL_CONTROL's
  `target` counts as a target system, as pymavlink's generator marks it) is handled and not forwarded;
- a broadcast (no target, or target 0) is handled and forwarded to every other link where some system was seen;
- a message for another system goes to the links where that system (and component, if given) was seen, and is
  handled here only if it is addressed to this sysid and no link had its component.
A link with MAVn_OPTIONS bit 1 (NO_FORWARD: `GCS_MAVLINK::init` makes it private, `set_channel_private`) learns
nothing and forwards nothing it receives, gets no forwarded heartbeat (`no_route_mask`) and is forwarded only what
is addressed exactly to a (sysid, component) seen on it. Pure: no sockets; `route` says where a message goes.
"""

from __future__ import annotations

NOT_FORWARDED = frozenset({"RADIO", "RADIO_STATUS", "ADSB_VEHICLE"})


def targets(msg) -> tuple[int, int]:
    """(target system, target component) of a message, -1 where it has no such field (`get_targets`)."""
    fields = msg.get_fieldnames()
    if "target_system" in fields:
        system = msg.target_system
    elif msg.get_type() == "MANUAL_CONTROL":
        system = msg.target
    else:
        system = -1
    return system, (msg.target_component if "target_component" in fields else -1)


class Router:
    """The routes learnt on the vehicle's links (channel numbers); `route(channel, msg)` per received message."""

    def __init__(self, sysid: int, compid: int = 1):
        self.sysid = sysid
        self.compid = compid
        self.routes: set[tuple[int, int, int]] = set()      # (sysid, compid, channel)

    def reset(self, sysid: int) -> None:
        """A reboot: the table is empty again (it lives in RAM), under the stored sysid."""
        self.sysid = sysid
        self.routes.clear()

    def route(self, channel: int, msg, channels: list[int], private: set[int] = frozenset()) -> tuple[bool, list[int]]:
        """(handle it here?, the channels to forward it to) for `msg` received on `channel`, of the vehicle's
        `channels`; `private`: the links with forwarding off (MAVn_OPTIONS bit 1)."""
        sender = (msg.get_srcSystem(), msg.get_srcComponent())
        if sender == (self.sysid, self.compid) or channel in private:
            return True, []
        if sender[0] != 0:
            self.routes.add((*sender, channel))
        kind = msg.get_type()
        if kind in NOT_FORWARDED:
            return True, []
        if kind == "HEARTBEAT":
            known = {c for s, k, c in self.routes if (s, k) == sender}
            return True, [c for c in channels if c != channel and c not in private and c not in known]
        system, component = targets(msg)
        broadcast_system, broadcast_component = system in (0, -1), component in (0, -1)
        match_system = broadcast_system or system == self.sysid
        local = match_system and (broadcast_component or component == self.compid)
        if local and not broadcast_system and not broadcast_component:
            return True, []
        forward = sorted({c for s, k, c in self.routes if c != channel and c in channels and (
            c not in private or (s, k) == (system, component)) and (
            broadcast_system or (s == system and (broadcast_component or k == component or not match_system)))})
        return local or (match_system and not forward), forward
