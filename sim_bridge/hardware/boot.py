"""The autopilot's power and boot on the vehicle's clock (a `reboot@T` brown-out, or MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN).

From the power loss the autopilot is OFF: it sends nothing, reads nothing, and its outputs send no pulse (ArduPilot
zeroes every output before it reboots: `AP_Vehicle::reboot`, `Sub::should_zero_rc_outputs_on_reboot`). At
FIRMWARE_START the firmware starts: time since boot (`AP_HAL::millis`, every time_boot_ms) counts from 0 again, the
parameters are loaded as stored, and `init_ardupilot` runs (INITIALISING): while it waits on its sensors,
`AP_Vehicle::scheduler_delay_callback` sends HEARTBEAT (system_status BOOT) and SYS_STATUS whenever a second of
uptime passed since the last (never in the first second) and nothing else goes out; here what arrives is still
ignored. At BOOT_TIME the main loop starts (RUNNING): `ap.initialised`, INFO "ArduPilot Ready" (the end of
`AP_Vehicle::setup`), the streams.

The times are chosen (not measured on a vehicle): a Pixhawk-class board spends about a second between a brown-out
and its firmware's first instruction (supply recovery, the bootloader's wait), then one to three seconds in init
(gyro calibration and barometer ground calibration at boot are most of it); a Navigator restarting only its ArduSub
process takes a few seconds too. BOOT_TIME = 3 s from the power loss to "ArduPilot Ready", 2 s of silence.
"""

from __future__ import annotations

OFF, INITIALISING, RUNNING = "off", "initialising", "running"
FIRMWARE_START = 1.0           # s from the power loss to the firmware's start (time since boot 0)
BOOT_TIME = 3.0                # s from the power loss to the main loop ("ArduPilot Ready")
DELAY_CALLBACK_PERIOD = 1.0    # s of uptime between the init's HEARTBEAT / SYS_STATUS


class Boot:
    """Where the autopilot is in its power cycle, in steps of the vehicle's clock (exact, as time_boot_ms is)."""

    def __init__(self, step: float):
        self.step = step
        self.start = 0                 # step at which the running firmware started (time since boot 0)
        self.ready = 0                 # step at which its main loop starts
        self.reboots = 0
        self._next_beat = 0.0

    def power_off(self, now: int) -> None:
        """The power is lost at step `now`."""
        self.start = now + round(FIRMWARE_START / self.step)
        self.ready = now + round(BOOT_TIME / self.step)
        self.reboots += 1
        self._next_beat = DELAY_CALLBACK_PERIOD

    def phase(self, now: int) -> str:
        if now < self.start:
            return OFF
        return INITIALISING if now < self.ready else RUNNING

    def uptime(self, now: int) -> float:
        """Seconds since the firmware started."""
        return (now - self.start) * self.step

    def delay_callback_due(self, now: int) -> bool:
        """Whether init's delay callback sends its HEARTBEAT and SYS_STATUS at step `now` (INITIALISING only)."""
        if self.phase(now) != INITIALISING or self.uptime(now) <= self._next_beat:
            return False
        self._next_beat = self.uptime(now) + DELAY_CALLBACK_PERIOD
        return True
