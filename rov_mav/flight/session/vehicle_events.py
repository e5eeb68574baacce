"""What the vehicle says about itself that ends a run: its own failsafes (ArduSub's texts and modes) and a reboot.

ArduSub 4.7 announces each failsafe in a STATUSTEXT (`ArduSub/failsafe.cpp`): "Leak Detected" (CRITICAL,
`Sub::failsafe_leak_check`, every 20 s while wet, whatever FS_LEAK_ENABLE says), "EKF bad" (WARNING,
`Sub::failsafe_ekf_check`), "Depth sensor error!" (CRITICAL, `Sub::failsafe_sensors_check`); the battery monitor says
"Battery N is low|critical V used mAh" (WARNING, `AP_BattMonitor::check_failsafes`), and the vehicle's action follows
(SURFACE or a disarm, `Sub::handle_battery_failsafe`). EKF_STATUS_REPORT without a horizontal position
(`NavEKF3_core::send_status_report`) means the estimator has lost its position source. A reboot shows as the
vehicle's clock (time_boot_ms) going back (`AP_HAL::millis` restarts at boot) and as HEARTBEAT's MAV_STATE_BOOT.
Pure: no I/O.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from pymavlink.dialects.v20 import ardupilotmega as mavlink

EXIT_REBOOT = 7            # exit status: the vehicle rebooted during the run
EXIT_FAILSAFE = 8          # exit status: the vehicle's own failsafe (leak, battery, estimator, depth sensor)
REBOOTED = 0.5             # vehicle s: a time this much earlier than the one a reboot went back from is after it
POSITION_FLAGS = mavlink.EKF_POS_HORIZ_REL | mavlink.EKF_POS_HORIZ_ABS


@dataclass(frozen=True)
class VehicleFault:
    """A failsafe the vehicle announced: `name` (leak, battery, estimator, depth sensor), `stop` (the run must end:
    only a low battery that merely warns does not)."""

    name: str
    stop: bool


_TEXTS = (
    (re.compile(r"^Leak Detected"), VehicleFault("leak", True)),
    (re.compile(r"^Battery \d+ is critical"), VehicleFault("battery critical", True)),
    (re.compile(r"^Battery \d+ is low"), VehicleFault("battery low", False)),
    (re.compile(r"^EKF bad"), VehicleFault("estimator (EKF) failsafe", True)),
    (re.compile(r"^Depth sensor error"), VehicleFault("depth sensor lost", True)),
)


def rebooted(before: float, after: float) -> str:
    """How a run names a reboot: the vehicle's clock went back from `before` to `after` s."""
    return f"the vehicle rebooted (its clock went back from {before:.1f} s to {after:.1f} s)"


class RebootWatch:
    """How a run meets a reboot of the vehicle, from the reboots its clock has seen (`VehicleClock.reboots`, detected
    by `vehicle_clock.is_reboot`) since the run began: it ends the run (`while_flying`: the vehicle is disarmed and
    its outputs are as stored in its parameters), a reboot first seen during the stop still names the exit
    (`while_stopping`), and mission times read across it as if the vehicle's clock had run on (`time_lost`)."""

    def __init__(self, clock):
        self.clock = clock
        self._before = len(clock.reboots)          # the reboots seen before this run

    def _new(self) -> list[tuple[float, float]]:
        return self.clock.reboots[self._before:]

    def while_flying(self, msg, kind: str, now: float) -> str | None:
        """Why the run must end (exit EXIT_REBOOT) on this message, or None: the clock went back, or a HEARTBEAT
        says the vehicle is booting (MAV_STATE_BOOT)."""
        new = self._new()
        if new or (kind == "HEARTBEAT" and msg.system_status == mavlink.MAV_STATE_BOOT):
            before, after = new[-1] if new else (now, 0.0)
            return f"{rebooted(before, after)}: it is disarmed, and its outputs are as stored in its parameters"
        return None

    def while_stopping(self, code: int, reason: str) -> tuple[int, str]:
        """The run's exit (code, reason), named as a reboot if one was first seen while it stopped."""
        new = self._new()
        if not new or code == EXIT_REBOOT:
            return code, reason
        return EXIT_REBOOT, f"{rebooted(*new[-1])}, first seen as: {reason}"

    def time_lost(self, t: float) -> float:
        """Vehicle s to add to a time `t` from the vehicle's clock for it to read as if no reboot had restarted it
        (a time more than REBOOTED s before the one a reboot went back from is from after it)."""
        return sum(before - after for before, after in self._new() if t < before - REBOOTED)


def failsafe_text(text: str) -> VehicleFault | None:
    """The failsafe a STATUSTEXT announces, or None."""
    for pattern, fault in _TEXTS:
        if pattern.match(text.strip()):
            return fault
    return None


def position_lost(flags: int) -> bool:
    """EKF_STATUS_REPORT.flags with neither a relative nor an absolute horizontal position (or in constant-position
    mode): the estimator has no position to give."""
    return not flags & POSITION_FLAGS or bool(flags & mavlink.EKF_CONST_POS_MODE)
