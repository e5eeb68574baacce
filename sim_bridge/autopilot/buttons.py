"""MANUAL_CONTROL's buttons as ArduSub acts on them (ArduSub/joystick.cpp,
`Sub::transform_manual_control_to_rc_override` and `Sub::handle_jsbutton_press`; AP_JSButton for the function numbers;
`Sub::default_js_buttons` for the defaults).

The 32 buttons are `buttons` | `buttons2` << 16. A button whose function is `shift` held in the same message makes
every pressed button act by its shift function (BTNn_SFUNCTION). Each pressed button acts on EVERY message while it
is held (a button held for a second at 25 Hz presses 25 times): arm, disarm and the mode buttons do not look at
whether it was held, so `arm_toggle` toggles on every message. Emulated: arm_toggle, arm, disarm and the mode
buttons (the mode change passes `Sub::set_mode`'s gates; the vehicle's, e.g. AUTO, refuse what it cannot fly).
Not emulated (this vehicle has no camera mount, lights, relays or scripts; gains, trims and input hold not modelled):
every other function, which does nothing here. Pure: `press(buttons)` returns the actions to take.
"""

from __future__ import annotations

from sim_bridge.modes.gates import MODES

BUTTONS = 32
DEFAULTS_UP_TO = 16              # `default_js_buttons` sets BTN0..15
SHIFT, ARM_TOGGLE, ARM, DISARM = 1, 2, 3, 4
MODE_OF = {5: MODES["MANUAL"], 6: MODES["STABILIZE"], 7: MODES["ALT_HOLD"], 8: MODES["POSHOLD"], 9: MODES["AUTO"],
           10: MODES["CIRCLE"], 11: MODES["GUIDED"], 12: MODES["ACRO"], 13: MODES["SURFTRAK"]}
# `Sub::default_js_buttons`: (function, shift function) of BTN0..15
DEFAULTS = ((0, 0), (5, 0), (7, 0), (6, 0), (4, 0), (1, 0), (3, 0), (21, 0), (48, 0), (23, 27), (22, 26), (42, 47),
            (43, 46), (33, 45), (32, 44), (0, 0))


def press(params, buttons: int) -> list[tuple[str, int]]:
    """The actions of one MANUAL_CONTROL's 32 button bits, in button order: ("arm", 1), ("arm", 0), ("toggle", 0) or
    ("mode", number)."""
    pressed = [i for i in range(BUTTONS) if buttons >> i & 1]
    shift = any(_function(params, i, False) == SHIFT for i in pressed)
    actions = []
    for i in pressed:
        function = _function(params, i, shift)
        if function == ARM_TOGGLE:
            actions.append(("toggle", 0))
        elif function in (ARM, DISARM):
            actions.append(("arm", int(function == ARM)))
        elif function in MODE_OF:
            actions.append(("mode", MODE_OF[function]))
    return actions


def has_disarm_function(params) -> bool:
    """`AP_Arming_Sub::has_disarm_function`: a button of BTN0..15 disarms (disarm or arm_toggle), or, when one of
    them is a shift button, a shift function does."""
    functions = [_function(params, i, False) for i in range(DEFAULTS_UP_TO)]
    if any(f in (ARM_TOGGLE, DISARM) for f in functions):
        return True
    return SHIFT in functions and any(_function(params, i, True) in (ARM_TOGGLE, DISARM) for i in range(DEFAULTS_UP_TO))


def _function(params, button: int, shift: bool) -> int:
    return int(params[f"BTN{button}_{'SFUNCTION' if shift else 'FUNCTION'}"])
