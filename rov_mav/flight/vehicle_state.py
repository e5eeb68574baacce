"""The state the law needs, (t, eta, nu), decoded from ArduSub's telemetry on the vehicle's own clock.

eta = [x, y, z (LOCAL_POSITION_NED), roll, pitch, yaw (ATTITUDE)]; nu = [R^T v_NED, p, q, r]: the NED velocity
(blended with the position's rate below `velocity_blend` rad/s: `VelocityBlend`) rotated into the body frame, and
ATTITUDE's body rates. A sample is complete once both messages arrived since the last one with time_boot_ms within
half a stream period of each other: a message whose partner was lost is dropped, so one lost packet does not pair
every later position with the next period's attitude. The sample's time is the newer of
their time_boot_ms, so dt is vehicle time whatever the vehicle's speedup.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rov_mav.flight.velocity_blend import VelocityBlend
from rov_mav.model.dynamics import rotation

STATE_MESSAGES = ("ATTITUDE", "LOCAL_POSITION_NED")
REBOOT_MS = 1000          # a stamp this far behind the last one is a new boot, not a late packet


@dataclass(frozen=True)
class State:
    t: float              # vehicle s since boot
    eta: np.ndarray       # (6,) NED position, Euler angles
    nu: np.ndarray        # (6,) body velocity
    received: float       # wall time (perf_counter) the completing message arrived


class StateDecoder:
    """Feed it the vehicle's messages; `update` says when a new state is complete, `state` decodes it."""

    def __init__(self, velocity_blend: float = 0.0):
        self.blend = VelocityBlend(velocity_blend)
        self.voltage: float | None = None     # V, from SYS_STATUS
        self.servo: np.ndarray | None = None  # (8,) SERVO1..8 PWM as the vehicle reports them
        self._latest: dict[str, object] = {}  # the latest message of each state kind
        self._fresh: set[str] = set()
        self._period_ms: dict[str, int] = {}  # the interval before each kind's latest message
        self._pair: tuple | None = None       # (ATTITUDE, LOCAL_POSITION_NED) of the latest complete sample

    @property
    def attitude(self):
        return self._latest.get("ATTITUDE")

    @property
    def position(self):
        return self._latest.get("LOCAL_POSITION_NED")

    def update(self, msg) -> bool:
        """Take one message; True when it completes a new (ATTITUDE, LOCAL_POSITION_NED) pair."""
        kind = msg.get_type()
        if kind == "SYS_STATUS" and msg.voltage_battery not in (0, 0xFFFF):
            self.voltage = msg.voltage_battery / 1000.0
        elif kind == "SERVO_OUTPUT_RAW":
            self.servo = np.array([getattr(msg, f"servo{i}_raw") for i in range(1, 9)], dtype=float)
        if kind not in STATE_MESSAGES:
            return False
        previous = self._latest.get(kind)
        if previous is not None and msg.time_boot_ms < previous.time_boot_ms - REBOOT_MS:
            self._fresh.clear()               # the vehicle rebooted: pair afresh on its new clock
            self._latest.clear()
            self._period_ms.clear()
            previous = None
        if previous is not None:
            if msg.time_boot_ms <= previous.time_boot_ms:
                return False                  # a duplicate or a late, reordered copy
            self._period_ms[kind] = msg.time_boot_ms - previous.time_boot_ms
        self._latest[kind] = msg
        (partner,) = (other for other in STATE_MESSAGES if other != kind)
        if partner in self._fresh and msg.time_boot_ms - self._latest[partner].time_boot_ms > self._tolerance_ms():
            self._fresh.discard(partner)      # its own partner was lost: it starts no pair
        self._fresh.add(kind)
        if len(self._fresh) < len(STATE_MESSAGES):
            return False
        self._fresh.clear()
        self._pair = (self._latest["ATTITUDE"], self._latest["LOCAL_POSITION_NED"])
        return True

    def _tolerance_ms(self) -> float:
        """Half the shortest stream period seen last: the most two halves of one sample can be apart."""
        return 0.5 * min(self._period_ms.values()) if self._period_ms else float("inf")

    def state(self, received: float) -> State:
        """The latest complete sample, its completing message received at wall time `received` (`update` must have
        completed one). A half of the next sample read since does not enter it."""
        a, p = self._pair
        t = max(a.time_boot_ms, p.time_boot_ms) / 1000.0
        eta = np.array([p.x, p.y, p.z, a.roll, a.pitch, a.yaw], dtype=float)
        v_ned = self.blend.update(t, eta[:3], np.array([p.vx, p.vy, p.vz], dtype=float))
        v_body = rotation(eta).T @ v_ned
        nu = np.array([*v_body, a.rollspeed, a.pitchspeed, a.yawspeed], dtype=float)
        return State(t, eta, nu, received)
