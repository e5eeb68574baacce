"""ArduSub's down-looking rangefinder and the range it holds in SURFTRAK, on the built-in vehicle.

The rangefinder (one instance, the MAVLink backend a BlueROV2's Ping service feeds):
- libraries/AP_RangeFinder/AP_RangeFinder_MAVLink.cpp `handle_msg`: a DISTANCE_SENSOR is taken only with the
  orientation RNGFND1_ORIENT (25, PITCH_270, down); its distance cm -> m; signal_quality 0 ("unknown") -> -1, 1
  ("invalid") -> 0, else as sent; the usable range is [max(RNGFND1_MIN, packet min), min(RNGFND1_MAX, packet max)]
  (the parameters alone when the packet gives 0 for both). `update`: nothing for 500 ms -> NoData (distance 0,
  quality -1); else the status by range (`AP_RangeFinder_Backend::update_status`: above the max OutOfRangeHigh, below
  the min OutOfRangeLow, else Good), and `set_status` counts Good updates (to 10) and zeroes the count otherwise.
- ArduSub/sensors.cpp `Sub::init_rangefinder`: enabled when a rangefinder faces down, decided once at boot (so
  RNGFND1_TYPE 10, MAVLink, and the orientation take a reboot); `Sub::read_rangefinder` at 20 Hz (Sub.cpp's
  scheduler table): healthy when Good with 3 or more Good updates in a row and a quality of -1 or at least
  RNGFND_SQ_MIN (90); the distance low-passed at 0.25 Hz (RANGEFINDER_WPNAV_FILT_HZ), the filter restarted from the
  reading after more than 1 s without health; the terrain's depth (the bottom under the vehicle, from its depth and
  the filtered range) frozen while unhealthy. `Sub::rangefinder_alt_ok`: enabled, healthy, healthy within 1 s.
  The tilt correction is compiled out in ArduSub (RANGEFINDER_TILT_CORRECTION disabled in ArduSub/config.h): the
  range is used as the height, tilted or not.

SURFTRAK (mode 21, ArduSub/mode_surftrak.cpp `ModeSurftrak`), ALT_HOLD's depth hold with a range target:
- the target is taken from the first healthy reading with the vehicle below SURFTRAK_DEPTH (-50 cm) and the throttle
  stick centred ("rangefinder target is %.2f meters"); a target outside the rangefinder's min and max is refused
  ("rangefinder target below minimum, ignored" / "above maximum") and the mode resets;
- while healthy, the depth target follows the bottom: the terrain's depth less the target, never shallower than
  SURFTRAK_DEPTH; the offset is moved toward that as AC_PosControl's terrain shaping does (`update_terrain`), here at
  most PILOT_SPEED_DN/UP and PILOT_ACCEL_Z (its jerk limit is left out);
- while unhealthy or out of range, nothing moves: the last depth target is held and the range target kept;
- the throttle stick moves the depth as in ALT_HOLD; when it is centred again the target becomes the old target less
  the depth gone down meanwhile (from the depth change, not the slow sonar);
- disarmed, at the surface, or a refused target: the target is forgotten (`reset`) and taken again at the next
  healthy reading; entering says "waiting for a rangefinder reading" without one, or "descend below %f meters to
  hold range" above SURFTRAK_DEPTH.
"""

from __future__ import annotations

import math

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sim_bridge.modes.stabilize import DEAD_ZONE

NOT_CONNECTED, NO_DATA, OUT_OF_RANGE_LOW, OUT_OF_RANGE_HIGH, GOOD = 0, 1, 2, 3, 4   # RangeFinder::Status
MAVLINK_TYPE = 10                      # RNGFND1_TYPE: MAVLink
DOWN = mavlink.MAV_SENSOR_ROTATION_PITCH_270                      # 25
TIMEOUT = 0.5                          # s: AP_RANGEFINDER_MAVLINK_TIMEOUT_MS
READ_PERIOD = 0.05                     # s: Sub::read_rangefinder at 20 Hz
HEALTH_COUNT = 3                       # RANGEFINDER_HEALTH_MAX
VALID_MAX = 10                         # range_valid_count's cap
FILTER_HZ = 0.25                       # RANGEFINDER_WPNAV_FILT_HZ
HEALTH_TIMEOUT = 1.0                   # s: RANGEFINDER_TIMEOUT_MS


class Rangefinder:
    """The down-looking rangefinder of one boot: what AP_RangeFinder and Sub's rangefinder state hold."""

    def __init__(self, params):
        self.enabled = int(params["RNGFND1_TYPE"]) == MAVLINK_TYPE and int(params["RNGFND1_ORIENT"]) == DOWN
        self.backend = int(params["RNGFND1_TYPE"]) == MAVLINK_TYPE
        self.status = NO_DATA if self.backend else NOT_CONNECTED
        self.distance = 0.0                    # m, the backend's last
        self.quality = -1                      # the backend's signal quality (-1 unknown)
        self.kind = 0                          # MAV_DISTANCE_SENSOR of the last packet
        self.packet_limits = (0.0, 0.0)        # m, the last packet's min and max distance
        self.limits = (0.0, 0.0)               # m, the usable range
        self.valid_count = 0
        self.healthy = False                   # Sub's alt_healthy
        self.filtered: float | None = None     # m, alt_filt
        self.last_healthy = -math.inf          # s
        self.terrain_depth: float | None = None   # m: the bottom's depth under the vehicle, as last measured
        self._last_message = -math.inf
        self._next_read = 0.0

    def handle(self, orientation: int, distance_cm: int, min_cm: int, max_cm: int, quality: int, kind: int,
               t: float) -> None:
        """A DISTANCE_SENSOR from any link or the companion (`AP_RangeFinder_MAVLink::handle_msg`)."""
        if not self.backend or orientation != DOWN:
            return
        self.distance = distance_cm / 100.0
        self.packet_limits = (min_cm / 100.0, max_cm / 100.0)
        self.kind = kind
        self.quality = -1 if quality == 0 else 0 if quality == 1 else int(quality)
        self._last_message = t

    def update(self, t: float, depth: float, params) -> None:
        """The backend's update and `Sub::read_rangefinder`, at 20 Hz of vehicle time t, with the vehicle's depth."""
        if t + 1e-9 < self._next_read:
            return
        self._next_read = t + READ_PERIOD
        if not self.backend:
            return
        low, high = self.range_parameters(params)
        packet_low, packet_high = self.packet_limits
        self.limits = (low, high) if packet_low == 0 and packet_high == 0 else (max(low, packet_low),
                                                                               min(high, packet_high))
        if t - self._last_message > TIMEOUT:
            self.status, self.distance, self.quality = NO_DATA, 0.0, -1
        elif self.distance > self.limits[1]:
            self.status = OUT_OF_RANGE_HIGH
        elif self.distance < self.limits[0]:
            self.status = OUT_OF_RANGE_LOW
        else:
            self.status = GOOD
        self.valid_count = min(self.valid_count + 1, VALID_MAX) if self.status == GOOD else 0
        if not self.enabled:
            return
        sq_min = params["RNGFND_SQ_MIN"]
        self.healthy = (self.status == GOOD and self.valid_count >= HEALTH_COUNT
                        and (self.quality == -1 or self.quality >= sq_min))
        if not self.healthy:
            return
        if self.filtered is None or t - self.last_healthy > HEALTH_TIMEOUT:
            self.filtered = self.distance
        else:
            alpha = READ_PERIOD / (READ_PERIOD + 1.0 / (2 * math.pi * FILTER_HZ))
            self.filtered += alpha * (self.distance - self.filtered)
        self.last_healthy = t
        self.terrain_depth = depth + self.filtered

    def reading(self) -> tuple | None:
        """(distance m, min m, max m, orientation, quality, MAV type) while the backend has data (`has_data`: not
        NotConnected nor NoData), for the autopilot's DISTANCE_SENSOR, RANGEFINDER and RFND."""
        if self.status in (NOT_CONNECTED, NO_DATA):
            return None
        return self.distance, self.limits[0], self.limits[1], DOWN, self.quality, self.kind

    def log_row(self) -> tuple | None:
        """RFND's (Dist m, Stat, Orient, Quality) while a backend is set up."""
        return (self.distance, self.status, DOWN, self.quality) if self.backend else None

    def alt_ok(self, t: float) -> bool:
        """`Sub::rangefinder_alt_ok`."""
        return self.enabled and self.healthy and t - self.last_healthy < HEALTH_TIMEOUT

    @staticmethod
    def range_parameters(params) -> tuple[float, float]:
        """(min, max) m: 4.7's RNGFND1_MIN/MAX in m, 4.5's RNGFND1_MIN_CM/MAX_CM."""
        if "RNGFND1_MIN" in params:
            return float(params["RNGFND1_MIN"]), float(params["RNGFND1_MAX"])
        return params["RNGFND1_MIN_CM"] / 100.0, params["RNGFND1_MAX_CM"] / 100.0


class Surftrak:
    """SURFTRAK's range target and the depth target it sets (ALT_HOLD's `Holds.depth`)."""

    def __init__(self):
        self.target: float | None = None       # m of range held (None: no target, ArduSub's -1)
        self._pilot_start: float | None = None # m: the depth when the pilot took the throttle stick
        self._rate = 0.0                       # m/s down: the shaped offset's rate

    def reset(self) -> None:
        self.target, self._pilot_start, self._rate = None, None, 0.0

    def enter(self, rangefinder: Rangefinder, depth: float, t: float, params, texts: list) -> None:
        """`ModeSurftrak::init` after ALT_HOLD's."""
        self.reset()
        if not rangefinder.alt_ok(t):
            texts.append((mavlink.MAV_SEVERITY_INFO, "waiting for a rangefinder reading"))
        elif -depth * 100.0 >= params["SURFTRAK_DEPTH"]:
            texts.append((mavlink.MAV_SEVERITY_WARNING,
                          f"descend below {params['SURFTRAK_DEPTH'] * 0.01:f} meters to hold range"))

    def run(self, holds, throttle: float, depth: float, at_surface: bool, rangefinder: Rangefinder, t: float,
            dt: float, params, texts: list) -> None:
        """`ModeSurftrak::control_range` for one loop: sets `holds.depth` (the depth target ALT_HOLD flies)."""
        if abs(throttle) > DEAD_ZONE:                  # ALT_HOLD's centred throttle
            if self.target is not None and self._pilot_start is None:
                self._pilot_start = depth
            return
        if self._pilot_start is not None:
            self._set_target(self.target - (depth - self._pilot_start), rangefinder, depth, params, texts)
            self._pilot_start = None
        if at_surface:
            self.reset()
            return
        if not rangefinder.alt_ok(t):
            return
        floor = -params["SURFTRAK_DEPTH"] / 100.0          # m: the shallowest depth held on range
        if self.target is None:
            if depth > floor:
                self._set_target(rangefinder.filtered, rangefinder, depth, params, texts)
            return
        goal = max(rangefinder.terrain_depth - self.target, floor)
        if holds.depth is None:
            holds.depth = depth
        holds.depth = self._shaped(holds.depth, goal, dt, params)

    def _set_target(self, target: float, rangefinder: Rangefinder, depth: float, params, texts: list) -> None:
        """`ModeSurftrak::set_rangefinder_target_cm`."""
        low, high = rangefinder.limits
        if -depth * 100.0 >= params["SURFTRAK_DEPTH"]:
            text = (mavlink.MAV_SEVERITY_WARNING,
                    f"descend below {params['SURFTRAK_DEPTH'] * 0.01:f} meters to set rangefinder target")
        elif target < low:
            text = (mavlink.MAV_SEVERITY_WARNING, "rangefinder target below minimum, ignored")
        elif target > high:
            text = (mavlink.MAV_SEVERITY_WARNING, "rangefinder target above maximum, ignored")
        else:
            self.target = target
            texts.append((mavlink.MAV_SEVERITY_INFO, f"rangefinder target is {target:.2f} meters"))
            return
        texts.append(text)
        self.reset()

    def _shaped(self, current: float, goal: float, dt: float, params) -> float:
        """The depth target moved toward `goal` at most PILOT_SPEED_DN (down) / PILOT_SPEED_UP (up) and PILOT_ACCEL_Z,
        braking to arrive (a stand-in for AC_PosControl's shaping of the terrain offset)."""
        down = (params["PILOT_SPEED_DN"] or params["PILOT_SPEED_UP"]) / 100.0
        up = params["PILOT_SPEED_UP"] / 100.0
        accel = params["PILOT_ACCEL_Z"] / 100.0
        error = goal - current
        braking = math.copysign(math.sqrt(2.0 * accel * abs(error)), error)
        wanted = min(max(braking, -up), down)
        self._rate += min(max(wanted - self._rate, -accel * dt), accel * dt)
        step = self._rate * dt
        if abs(step) >= abs(error):
            self._rate = 0.0
            return goal
        return current + step
