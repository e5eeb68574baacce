"""The state the law needs, (t, eta, nu), decoded from ArduSub's telemetry on the vehicle's own clock.

eta = [x, y, z (LOCAL_POSITION_NED, less a jump of the estimate still being taken in: `EstimateJumps`), roll,
pitch, yaw (ATTITUDE)]; nu = [R^T v_NED, p, q, r]: the NED velocity rotated into the body frame, and ATTITUDE's
body rates; the position and the NED velocity shaped as a run shapes them (`EstimateShaping`). The older of
the two messages is brought forward to the newer one's time by its own rates (the reported NED velocity, the body
rates through T(Theta)), so that position and attitude are of one instant.
A sample is complete once both messages arrived since the last one with time_boot_ms within
half a stream period of each other: a message whose partner was lost is dropped, so one lost packet does not pair
every later position with the next period's attitude. Streams exactly half a period apart (the built-in vehicle's)
could pair either way; a half as near the next message as the last (within TIE_MS) keeps the pairing the streams had,
so a loss does not shift every later sample's position by half a period. The sample's time is the newer of
their time_boot_ms, so dt is vehicle time whatever the vehicle's speedup.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rov_mav.flight.session.vehicle_clock import is_reboot
from rov_mav.flight.state.estimate_shaping import EstimateShaping
from rov_mav.model.dynamics import euler_rate_matrix, rotation

STATE_MESSAGES = ("ATTITUDE", "LOCAL_POSITION_NED")
TIE_MS = 1                # halves this close to half a period apart could pair either way (stamps are whole ms)


@dataclass(frozen=True)
class State:
    t: float              # vehicle s since boot
    eta: np.ndarray       # (6,) NED position, Euler angles
    nu: np.ndarray        # (6,) body velocity
    received: float       # wall time (perf_counter) the completing message arrived
    reported: np.ndarray | None = None   # (3,) the vehicle's own position estimate at t, whatever eta's came from


class StateDecoder:
    """Feed it the vehicle's messages; `update` says when a new state is complete, `state` decodes it."""

    def __init__(self, velocity_blend: float = 0.0, steady: bool = False):
        self.shaping = EstimateShaping(velocity_blend, steady)   # steady: jumps taken in at a flyable pace (a run)
        self.voltage: float | None = None     # V, from SYS_STATUS
        self.servo: np.ndarray | None = None  # (8,) the motors' outputs' PWM as the vehicle reports them
        self.outputs = tuple(range(1, 9))     # the output (1-based) of each motor (`vehicle_frame.MotorOutputs`)
        self._latest: dict[str, object] = {}  # the latest message of each state kind
        self._fresh: set[str] = set()
        self._period_ms: dict[str, int] = {}  # the interval before each kind's latest message
        self._pair: tuple | None = None       # (ATTITUDE, LOCAL_POSITION_NED) of the latest complete sample
        self._leader: str | None = None       # the kind that came first in the latest complete sample

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
            self.servo = np.array([getattr(msg, f"servo{i}_raw") for i in self.outputs], dtype=float)
        if kind not in STATE_MESSAGES:
            return False
        previous = self._latest.get(kind)
        if previous is not None and is_reboot(previous.time_boot_ms / 1000.0, msg.time_boot_ms / 1000.0):
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
        if (self._leader == kind
                and msg.time_boot_ms - self._latest[partner].time_boot_ms >= self._tolerance_ms() - TIE_MS):
            self._fresh.discard(partner)      # as near the next period's half: pair as the streams did
            return False
        self._leader = partner
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
        t_attitude, t_position = a.time_boot_ms / 1000.0, p.time_boot_ms / 1000.0
        t = max(t_attitude, t_position)
        reported_v = np.array([p.vx, p.vy, p.vz], dtype=float)
        rates = np.array([a.rollspeed, a.pitchspeed, a.yawspeed], dtype=float)
        eta = np.array([p.x, p.y, p.z, a.roll, a.pitch, a.yaw], dtype=float)
        # the older half brought forward to the sample's time by its own rates (by half a period at most)
        eta[:3] += reported_v * (t - t_position)
        eta[3:] += euler_rate_matrix(eta) @ rates * (t - t_attitude)
        reported = eta[:3].copy()
        eta[:3], v_ned = self.shaping.shape(t, eta[:3], reported_v)
        v_body = rotation(eta).T @ v_ned
        nu = np.array([*v_body, a.rollspeed, a.pitchspeed, a.yawspeed], dtype=float)
        return State(t, eta, nu, received, reported)
