"""ArduSub's SURFACE mode (9) and surface detector on the built-in vehicle.

- Entry: `sim_bridge.modes.gates.refusal` (4.7's `ModeSurface::init` never refuses; 4.5's needs the depth sensor).
- `ModeSurface::run`, armed, with a depth sensor (not failed): at the surface, ALT_HOLD (ModeReason
  SURFACE_COMPLETE; no disarm); else the depth target rises at min(WPNAV_SPEED_UP, PILOT_SPEED_UP) cm/s (the
  waypoint navigator's default climb, capped by the position controller's limit), through the depth hold of
  `sim_bridge.modes.stabilize`, the pilot keeping roll and pitch (lean angles), yaw rate, forward and lateral.
  Without one
  (4.7, `nobaro_mode`): throttle 0.5 + SFC_NOBARO_THST x 0.005 (AP_Motors6DOF's throttle axis 2 (throttle - 0.5)),
  no surface detection. Disarmed: nothing runs.
- `Sub::update_surface_and_bottom_detector` (every loop): at the surface once the depth is less than
  -SURFACE_DEPTH/100 m, until it is SURFACE_HYSTERESIS deeper than that; never while disarmed. Without a depth sensor
  ArduSub looks for a stalled climb; this vehicle does not (its nobaro SURFACE rises until the mode is changed).
- ALT_HOLD at the surface (`ModeAlthold::control_depth`): the depth target no shallower than -SURFACE_DEPTH/100 m
  (`min_depth`).
"""

from __future__ import annotations

SURFACE_HYSTERESIS = 0.05      # m
CM = 0.01


def climb_rate(params) -> float:
    """m/s up that SURFACE asks of the depth hold (ModeSurface::run: constrain(|WPNAV_SPEED_UP|, 1, speed up))."""
    return min(max(abs(params.guided_gains()["WPNAV_SPEED_UP"]), 1.0), max(params["PILOT_SPEED_UP"], 1.0)) * CM


def nobaro_throttle(params) -> float:
    """The mixer's throttle axis (up positive) of a SURFACE without a depth sensor (4.7, SFC_NOBARO_THST %)."""
    return min(max(params["SFC_NOBARO_THST"], -100.0), 100.0) * 0.01


def surface_depth(params) -> float:
    """Depth in m (positive down) under which the vehicle counts as at the surface."""
    return -params["SURFACE_DEPTH"] * CM


class SurfaceDetector:
    """`ap.at_surface` from the depth estimate."""

    def __init__(self):
        self.at_surface = False

    def update(self, armed: bool, depth: float | None, params) -> bool:
        """`depth` in m (None: no depth sensor to read); the new state."""
        if not armed or depth is None:
            self.at_surface = False
        else:
            limit = surface_depth(params) + (SURFACE_HYSTERESIS if self.at_surface else 0.0)
            self.at_surface = depth < limit
        return self.at_surface
