"""ArduSub's failsafes on the built-in vehicle, as ArduSub/failsafe.cpp keeps them: pilot input, GCS, leak, battery
monitor, EKF variance, depth sensor, terrain.

ArduSub 4.7's (ArduSub/failsafe.cpp @01218ccc; 4.5 the same unless said), on the time since boot, at their loop rates:
- Pilot-input failsafe (`Sub::failsafe_pilot_input_check`, checked every loop): after FS_PILOT_TIMEOUT with no
  pilot input, "Lost manual control" (CRITICAL, once), `Sub::set_neutral_controls`, disarm if FS_PILOT_INPUT is 2. It
  also fires at boot. `set_neutral_controls` (4.5 and 4.7, ArduSub/joystick.cpp) writes each pilot channel's
  (1-6) RCn_TRIM into its input, not an override: it lasts until the next RC read, which takes any override still
  live back (RC_OVERRIDE_TIME -1: the last overrides return at once; 0: overrides are off and the input stays at
  trim); 7 and 8 keep theirs.
- GCS failsafe (`Sub::failsafe_gcs_check`, ArduSub/failsafe.cpp, 4.5 and 4.7; checked at 3.3 Hz, only once a GCS
  heartbeat was seen): after FS_GCS_TIMEOUT without a heartbeat from the GCS sysid, "MYGCS: <MAV_GCS_SYSID>,
  heartbeat lost" (WARNING) at most every 30 s, armed or not, and never in the first 30 s of uptime (the time of the
  last warning starts at 0); while armed, once: warn (1), disarm (2), hold (3: ALT_HOLD) or surface (4: SURFACE),
  disarming if that mode change is refused. On 4.7 traffic coming back clears it with "GCS Failsafe Cleared"
  (WARNING); 4.5 clears it silently.
- Leak (`Sub::failsafe_leak_check`, three_hz_loop): dry or FS_LEAK_ENABLE 0 clears it. Wet: CRITICAL "Leak Detected"
  whenever more than 20 s passed since the last one (the last starts at 0: none in the first 20 s after boot), armed
  or not; the first wet check latches the failsafe and, only if FS_LEAK_ENABLE is 2 and the vehicle is armed then,
  SURFACE (arming later during the same leak does not).
- Battery (AP_BattMonitor `check_failsafes`, from `read` at 10 Hz, only while armed; the backend's
  `update_failsafes` / `check_failsafe_types`): critical before low; a voltage below BATT_CRT_VOLT / BATT_LOW_VOLT
  (0: off) for more than BATT_LOW_TIMER s (0: never), or capacity left (BATT_CAPACITY - consumed) below
  BATT_CRT_MAH / BATT_LOW_MAH (at once). Each step up sends WARNING "Battery 1 is low|critical %.2fV used %.0f mAh"
  (raw volts, mAh since boot) and latches `has_failsafed` (until a reboot here); the action (BATT_FS_LOW_ACT /
  BATT_FS_CRT_ACT: 2 disarm, 3 SURFACE, `Sub::handle_battery_failsafe`) runs if its priority (disarm > surface >
  warn > none) is at least the highest acted on so far.
- EKF (`Sub::failsafe_ekf_check`, 50 Hz, armed or not): FS_EKF_ACTION 0 clears it; the compass or velocity variance
  at or above FS_EKF_THRESH for 2 s latches it, with WARNING "EKF bad" (if 20 s passed since the last; the last
  starts at 0) and a disarm when FS_EKF_ACTION is 2; good variances clear it.
- Depth sensor (`Sub::failsafe_sensors_check`, 50 Hz): only with a depth sensor found at boot. Unhealthy: CRITICAL
  "Depth sensor error!" once, and from ALT_HOLD, SURFACE or a mode needing a position to MANUAL (a refused change
  disarms); healthy again clears it.
- Terrain (`Sub::failsafe_terrain_check`, three_hz_loop; `failsafe_terrain_set_status`, `failsafe_terrain_on_event`,
  `failsafe_terrain_act` in failsafe.cpp / events.cpp, a 4.5+-era copy): AUTO's navigator reports each loop whether
  it had the terrain data a terrain leg needs (`terrain_status`); in AUTO or GUIDED, failures spanning more than 1 s
  (FS_TERRAIN_TIMEOUT_MS; 0.1 s of successes clears them) send CRITICAL "Failsafe terrain triggered" and the event:
  with the rangefinder enabled, AUTO's recovery (`sim_bridge.modes.auto.Auto.recover_start`), else (or when it
  cannot start) the action FS_TERRAIN_ENAB: 0 disarm (the default), 1 POSHOLD (ALT_HOLD if refused), 2 SURFACE.
  Data again, or another mode, clears it.
`triggered(firmware)` is `Sub::any_failsafe_triggered` (Sub.h; 4.7: pilot input, GCS, battery, EKF, leak, sensor
health; 4.5: pilot input, GCS, battery, EKF).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from sim_bridge.modes.gates import MODES, NEED_DEPTH

CRITICAL, WARNING = 2, 4                              # MAV_SEVERITY
LEAK_PERIOD, BATTERY_PERIOD, FAST_PERIOD = 0.3, 0.1, 0.02   # s: three_hz_loop, update_batt_compass, fifty_hz_loop
LEAK_WARN_PERIOD = EKF_WARN_PERIOD = 20.0             # s
EKF_BAD_FOR = 2.0                                      # s
FS_LEAK_SURFACE = 2
FS_EKF_DISARM = 2
FS_GCS_DISARM, FS_GCS_HOLD, FS_GCS_SURFACE = 2, 3, 4        # 1: warn only
FS_PILOT_DISARM = 2
GCS_CHECK_PERIOD = 0.3                                 # s: ArduSub's 3.3 Hz loop
GCS_WARN_PERIOD = 30.0                                 # s between "heartbeat lost" warnings
TERRAIN_TIMEOUT = 1.0                                  # s: FS_TERRAIN_TIMEOUT_MS (ArduSub/config.h)
TERRAIN_CLEAR = 0.1                                    # s of successes that clear the failures
FS_TERRAIN_HOLD, FS_TERRAIN_SURFACE = 1, 2             # FS_TERRAIN_ENAB; 0 (or any other): disarm
PILOT_CHANNELS = 6                                     # `set_neutral_controls`: channels 1-6 to their trim
ACTION_DISARM, ACTION_SURFACE = 2, 3
PRIORITIES = (ACTION_DISARM, ACTION_SURFACE, 1, 0)     # Sub.h `_failsafe_priorities`, most severe first
BATTERY_NONE, BATTERY_LOW, BATTERY_CRITICAL = 0, 1, 2
BATTERY_NAMES = {BATTERY_LOW: "low", BATTERY_CRITICAL: "critical"}


@dataclass
class Readings:
    """What the autopilot reads this pass: the leak probe, the battery monitor, the EKF's variances, the depth
    sensor."""

    leak: bool = False
    voltage: float = 16.8                  # V, raw
    consumed_mah: float = 0.0              # since boot
    velocity_variance: float = 0.0
    compass_variance: float = 0.0
    depth_healthy: bool = True
    depth_present: bool = True             # found at boot (`ap.depth_sensor_present`)


class Failsafes:
    """The state of the failsafes of one boot; `update(sub, t, sensors)` every main-loop pass, `heard_gcs` and
    `heard_pilot` as the inputs that refresh them arrive."""

    def __init__(self, t: float = 0.0):
        self.pilot = False                          # `failsafe.pilot_input`
        self.gcs = False                            # `failsafe.gcs`
        self._pilot_seen = t
        self._gcs_seen: float | None = None         # no GCS heard yet: no GCS failsafe
        self._last_gcs_warn = 0.0                   # `last_gcs_warn_ms` starts at 0: boot
        self.leak = False
        self.battery = BATTERY_NONE
        self.battery_failsafed = False              # `AP_BattMonitor::has_failsafed`
        self.ekf = False
        self.depth = False                          # `failsafe.sensor_health`
        self._last_leak_warn = 0.0
        self._last_ekf_warn = 0.0
        self._ekf_good = 0.0
        self._priority = math.inf                   # `_highest_failsafe_priority`
        self._low_since: float | None = None
        self._critical_since: float | None = None
        self.terrain = False                        # `failsafe.terrain`
        self._terrain_failures: tuple[float, float] | None = None   # (first, last) failure, s
        self._next = {"leak": t, "battery": t, "fast": t, "gcs": t}

    def heard_gcs(self, t: float) -> None:
        """A heartbeat from a GCS sysid (`Sub::failsafe.last_heartbeat_ms`)."""
        self._gcs_seen = t

    def heard_pilot(self, t: float) -> None:
        """Pilot input (RC overrides or MANUAL_CONTROL from a GCS sysid): it refreshes the GCS failsafe too."""
        self._pilot_seen = self._gcs_seen = t

    def triggered(self, firmware: str) -> bool:
        """Their part of `Sub::any_failsafe_triggered` (Sub.h: 4.7 lists leak and sensor health too)."""
        common = self.pilot or self.gcs or self.battery_failsafed or self.ekf
        return common if firmware == "4.5" else common or self.leak or self.depth

    def update(self, sub, t: float, sensors: Readings) -> None:
        """Run the checks due at time since boot t on `sub` (an ArduSub: params, rc, armed, mode, set_mode, arm,
        texts)."""
        self._pilot_input_check(sub, t)
        if t >= self._next["fast"]:
            self._next["fast"] = t + FAST_PERIOD
            self._ekf_check(sub, t, sensors)
            self._depth_check(sub, sensors)
        if t >= self._next["battery"]:
            self._next["battery"] = t + BATTERY_PERIOD
            if sub.armed:
                self._battery_check(sub, t, sensors)
        if t >= self._next["leak"]:
            self._next["leak"] = t + LEAK_PERIOD
            self._leak_check(sub, t, sensors)
        if t >= self._next["gcs"]:
            self._next["gcs"] = t + GCS_CHECK_PERIOD
            self._gcs_check(sub, t)
            self._terrain_check(sub, t)

    def _pilot_input_check(self, sub, t: float) -> None:
        """`Sub::failsafe_pilot_input_check`, every loop."""
        if sub.params["FS_PILOT_INPUT"] == 0 or t < self._pilot_seen + sub.params["FS_PILOT_TIMEOUT"]:
            self.pilot = False
            return
        if self.pilot:
            return
        self.pilot = True
        sub.texts.append((CRITICAL, "Lost manual control"))
        for ch in range(PILOT_CHANNELS):                    # `Sub::set_neutral_controls`
            sub.rc.radio_in[ch] = int(sub.params[f"RC{ch + 1}_TRIM"])
        if sub.params["FS_PILOT_INPUT"] == FS_PILOT_DISARM:
            sub.arm(False)

    def _gcs_check(self, sub, t: float) -> None:
        """`Sub::failsafe_gcs_check`, at 3.3 Hz."""
        action = int(sub.params["FS_GCS_ENABLE"])
        if action == 0 or self._gcs_seen is None:
            return
        if t - self._gcs_seen < sub.params["FS_GCS_TIMEOUT"]:
            if self.gcs and sub.params.firmware == "4.7":
                sub.texts.append((WARNING, "GCS Failsafe Cleared"))
            self.gcs = False
            return
        if t - self._last_gcs_warn > GCS_WARN_PERIOD:
            self._last_gcs_warn = t
            sub.texts.append((WARNING, f"MYGCS: {sub.params.gcs_sysid}, heartbeat lost"))
        if self.gcs or not sub.armed:
            return
        self.gcs = True
        if action == FS_GCS_DISARM:
            sub.arm(False)
        elif action in (FS_GCS_HOLD, FS_GCS_SURFACE):
            if not sub.set_mode(MODES["ALT_HOLD" if action == FS_GCS_HOLD else "SURFACE"]):
                sub.arm(False)

    def terrain_status(self, data_ok: bool, t: float) -> None:
        """`Sub::failsafe_terrain_set_status`: whether the terrain data a terrain leg needs was there this loop."""
        if not data_ok:
            first = self._terrain_failures[0] if self._terrain_failures else t
            self._terrain_failures = (first, t)
        elif self._terrain_failures and t - self._terrain_failures[1] > TERRAIN_CLEAR:
            self._terrain_failures = None

    def _terrain_check(self, sub, t: float) -> None:
        """`Sub::failsafe_terrain_check`, at 3.3 Hz."""
        failures = self._terrain_failures
        trigger = sub.mode in (MODES["AUTO"], MODES["GUIDED"]) and failures is not None and \
            failures[1] - failures[0] > TERRAIN_TIMEOUT
        if trigger == self.terrain:
            return
        if not trigger:
            self.terrain = False
            return
        sub.texts.append((CRITICAL, "Failsafe terrain triggered"))
        self.terrain_event(sub, t)

    def terrain_event(self, sub, t: float) -> None:
        """`Sub::failsafe_terrain_on_event`: AUTO's recovery if the rangefinder is enabled and it can start, else the
        action."""
        self.terrain = True
        if not sub.rangefinder.enabled or not sub.auto.recover_start(sub, t):
            self.terrain_act(sub)

    def terrain_act(self, sub) -> None:
        """`Sub::failsafe_terrain_act` by FS_TERRAIN_ENAB."""
        action = int(sub.params["FS_TERRAIN_ENAB"])
        if action == FS_TERRAIN_HOLD:
            if not sub.set_mode(MODES["POSHOLD"]):
                sub.set_mode(MODES["ALT_HOLD"])
        elif action == FS_TERRAIN_SURFACE:
            sub.set_mode(MODES["SURFACE"])
        else:
            sub.arm(False)

    def _leak_check(self, sub, t: float, sensors: Readings) -> None:
        action = int(sub.params["FS_LEAK_ENABLE"])
        if not sensors.leak or action == 0:
            self.leak = False
            return
        if t > self._last_leak_warn + LEAK_WARN_PERIOD:
            self._last_leak_warn = t
            sub.texts.append((CRITICAL, "Leak Detected"))
        if self.leak:
            return
        self.leak = True
        if action == FS_LEAK_SURFACE and sub.armed:
            sub.set_mode(MODES["SURFACE"])

    def _battery_check(self, sub, t: float, sensors: Readings) -> None:
        state = self._battery_state(sub.params, t, sensors)
        if state <= self.battery:
            return
        p = sub.params
        action = int(p["BATT_FS_LOW_ACT"] if state == BATTERY_LOW else p["BATT_FS_CRT_ACT"])
        sub.texts.append((WARNING, f"Battery 1 is {BATTERY_NAMES[state]} {sensors.voltage:.2f}V used "
                                   f"{sensors.consumed_mah:.0f} mAh"))
        self.battery_failsafed = True
        self.battery = state
        priority = PRIORITIES.index(action) if action in PRIORITIES else len(PRIORITIES)
        if priority <= self._priority:
            self._priority = priority
            if action == ACTION_SURFACE:
                sub.set_mode(MODES["SURFACE"])
            elif action == ACTION_DISARM:
                sub.arm(False)

    def _battery_state(self, p, t: float, sensors: Readings) -> int:
        """`update_failsafes`: the state the monitor reads now, with its voltage timers."""
        timeout = p["BATT_LOW_TIMER"]
        left = p["BATT_CAPACITY"] - sensors.consumed_mah
        volts = sensors.voltage

        def below(threshold: float) -> bool:
            return volts > 0 and threshold > 0 and volts < threshold

        if below(p["BATT_CRT_VOLT"]):
            if self._critical_since is None:
                self._critical_since = t
            elif timeout > 0 and t - self._critical_since > timeout:
                return BATTERY_CRITICAL
        else:
            self._critical_since = None
        if p["BATT_CRT_MAH"] > 0 and left < p["BATT_CRT_MAH"]:
            return BATTERY_CRITICAL
        if below(p["BATT_LOW_VOLT"]):
            if self._low_since is None:
                self._low_since = t
            elif timeout > 0 and t - self._low_since > timeout:
                return BATTERY_LOW
        else:
            self._low_since = None
        if p["BATT_LOW_MAH"] > 0 and left < p["BATT_LOW_MAH"]:
            return BATTERY_LOW
        return BATTERY_NONE

    def _ekf_check(self, sub, t: float, sensors: Readings) -> None:
        action, threshold = int(sub.params["FS_EKF_ACTION"]), sub.params["FS_EKF_THRESH"]
        good = sensors.compass_variance < threshold and sensors.velocity_variance < threshold
        if action == 0 or good:
            self._ekf_good = t
            self.ekf = False
            return
        if t < self._ekf_good + EKF_BAD_FOR:
            self.ekf = False
            return
        if self.ekf:
            return
        self.ekf = True
        if t > self._last_ekf_warn + EKF_WARN_PERIOD:
            self._last_ekf_warn = t
            sub.texts.append((WARNING, "EKF bad"))
        if action == FS_EKF_DISARM:
            sub.arm(False)

    def _depth_check(self, sub, sensors: Readings) -> None:
        if not sensors.depth_present:
            return
        if sensors.depth_healthy:
            self.depth = False
            return
        if self.depth:
            return
        self.depth = True
        sub.texts.append((CRITICAL, "Depth sensor error!"))
        if sub.mode in NEED_DEPTH and not sub.set_mode(MODES["MANUAL"]):
            sub.arm(False)
