"""The state the law needs, (t, eta, nu), decoded from ArduSub's telemetry on the vehicle's own clock.

eta = [x, y, z (LOCAL_POSITION_NED), roll, pitch, yaw (ATTITUDE)]; nu = [R^T v_NED, p, q, r]: the NED velocity
rotated into the body frame, and ATTITUDE's body rates. A sample is complete once both messages arrived since the
last one; its time is the newer of their time_boot_ms, so dt is vehicle time whatever the vehicle's speedup.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rov_mav.model.dynamics import rotation

STATE_MESSAGES = ("ATTITUDE", "LOCAL_POSITION_NED")


@dataclass(frozen=True)
class State:
    t: float              # vehicle s since boot
    eta: np.ndarray       # (6,) NED position, Euler angles
    nu: np.ndarray        # (6,) body velocity
    received: float       # wall time (perf_counter) the completing message arrived


class StateDecoder:
    """Feed it the vehicle's messages; `update` says when a new state is complete, `state` decodes it."""

    def __init__(self):
        self.attitude = None
        self.position = None
        self.voltage: float | None = None     # V, from SYS_STATUS
        self.servo: np.ndarray | None = None  # (8,) SERVO1..8 PWM as the vehicle reports them
        self._fresh: set[str] = set()

    def update(self, msg) -> bool:
        """Take one message; True when it completes a new (ATTITUDE, LOCAL_POSITION_NED) pair."""
        kind = msg.get_type()
        if kind == "ATTITUDE":
            self.attitude = msg
        elif kind == "LOCAL_POSITION_NED":
            self.position = msg
        elif kind == "SYS_STATUS" and msg.voltage_battery not in (0, 0xFFFF):
            self.voltage = msg.voltage_battery / 1000.0
        elif kind == "SERVO_OUTPUT_RAW":
            self.servo = np.array([getattr(msg, f"servo{i}_raw") for i in range(1, 9)], dtype=float)
        if kind not in STATE_MESSAGES:
            return False
        self._fresh.add(kind)
        if len(self._fresh) < len(STATE_MESSAGES):
            return False
        self._fresh.clear()
        return True

    def state(self, received: float) -> State:
        """The latest state, its completing message received at wall time `received` (both must have arrived)."""
        a, p = self.attitude, self.position
        eta = np.array([p.x, p.y, p.z, a.roll, a.pitch, a.yaw], dtype=float)
        v_body = rotation(eta).T @ np.array([p.vx, p.vy, p.vz])
        nu = np.array([*v_body, a.rollspeed, a.pitchspeed, a.yawspeed], dtype=float)
        return State(max(a.time_boot_ms, p.time_boot_ms) / 1000.0, eta, nu, received)
