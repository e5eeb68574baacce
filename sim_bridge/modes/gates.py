"""ArduSub's flight-mode numbers and the gates a mode change passes (`Sub::set_mode`, ArduSub/mode.cpp), in order:
- a mode ArduSub does not have: "No such mode N" (`notify_no_such_mode`); one it has that this vehicle does not
  fly (CIRCLE, MOTOR_DETECT): "Flight mode change failed NAME";
- a mode that `requires_GPS()` (GUIDED, POSHOLD, AUTO, CIRCLE; ArduSub/mode.h) without `Sub::position_ok`:
  "Mode change failed: NAME requires position";
- the mode's `init`: ALT_HOLD (`ModeAlthold::init`), SURFTRAK (`ModeSurftrak::init` runs ALT_HOLD's first) and, in
  4.5, SURFACE need `Sub::control_check_barometer` (a depth
  sensor found at boot and no depth-sensor failsafe; its own warning first); 4.7's SURFACE never refuses (it rises
  on SFC_NOBARO_THST instead, PR #29996); AUTO (`ModeAuto::init`, ArduSub/mode_auto.cpp) needs a mission past
  home's slot (`AP_Mission::present`), armed or not; a refused init adds "Flight mode change failed NAME".
Every text is a WARNING. The names are the ones this bridge has always reported (upper case, as 4.5's
`Mode::name()`; newer masters spell some in title case: not checked for 4.7).
"""

from __future__ import annotations

MODES = {"STABILIZE": 0, "ACRO": 1, "ALT_HOLD": 2, "AUTO": 3, "GUIDED": 4, "CIRCLE": 7, "SURFACE": 9,
         "POSHOLD": 16, "MANUAL": 19, "MOTOR_DETECT": 20, "SURFTRAK": 21}
MODE_NAMES = {number: name for name, number in MODES.items()}
SUPPORTED_MODES = frozenset({MODES[m] for m in ("STABILIZE", "ACRO", "ALT_HOLD", "POSHOLD", "MANUAL", "GUIDED",
                                                "SURFACE", "SURFTRAK", "AUTO")})
GUIDED_FLAG_MODES = frozenset({MODES[m] for m in ("GUIDED", "AUTO", "POSHOLD", "CIRCLE")})
REQUIRES_POSITION = frozenset({MODES[m] for m in ("GUIDED", "AUTO", "POSHOLD", "CIRCLE")})
# Modes the depth-sensor failsafe leaves for MANUAL (`Sub::failsafe_sensors_check`): ALT_HOLD, SURFACE, and those
# that require a position.
NEED_DEPTH = REQUIRES_POSITION | {MODES["ALT_HOLD"], MODES["SURFACE"], MODES["SURFTRAK"]}
NO_DEPTH_SENSOR = "Depth sensor is not connected."
DEPTH_SENSOR_ERROR = "Depth sensor error."


def barometer_refusal(depth_present: bool, depth_failsafe: bool) -> str | None:
    """`Sub::control_check_barometer` (ArduSub.cpp): the warning it sends, or None when depth can be held. (Its SITL
    build skips the check; a vehicle's does not, and that is what is emulated.)"""
    if not depth_present:
        return NO_DEPTH_SENSOR
    if depth_failsafe:
        return DEPTH_SENSOR_ERROR
    return None


def refusal(mode: int, firmware: str, position_ok: bool, depth_present: bool, depth_failsafe: bool,
            mission_present: bool = False) -> list[str]:
    """The warnings `Sub::set_mode` sends when it refuses `mode`, in order; empty when the mode can be entered.
    `mission_present`: a mission is stored past home's slot (AUTO's)."""
    name = MODE_NAMES.get(mode)
    if name is None:
        return [f"No such mode {mode}"]
    if mode not in SUPPORTED_MODES:
        return [f"Flight mode change failed {name}"]
    if mode in REQUIRES_POSITION and not position_ok:
        return [f"Mode change failed: {name} requires position"]
    if mode in (MODES["ALT_HOLD"], MODES["SURFTRAK"]) or (mode == MODES["SURFACE"] and firmware == "4.5"):
        text = barometer_refusal(depth_present, depth_failsafe)
        if text is not None:
            return [text, f"Flight mode change failed {name}"]
    if mode == MODES["AUTO"] and not mission_present:
        return [f"Flight mode change failed {name}"]
    return []
