"""MANUAL_CONTROL -> RC overrides, as ArduSub maps a pilot's joystick: channels 1-11 on 4.5 (4.5.3), 1-8 on 4.7.

Source: ArduSub/joystick.cpp, `Sub::init_joystick` (the gain, fixed at boot) and
`Sub::transform_manual_control_to_rc_override` (the mapping), called by `GCS_MAVLINK_Sub::handle_manual_control_axes`
(ArduSub/GCS_Mavlink.cpp). With no buttons held and no trims or input hold (buttons are ignored here):

    rpy   = 0.4 * gain                 throttle = 0.8 * gain * JS_THR_GAIN      base = int16(1500 - 500 * throttle)
    ch1 pitch   = 1500 + s             ch2 roll  = 1500 + t          (s, t are added whether or not flagged valid)
    ch3 throttle = z * throttle + base ch4 yaw   = r * rpy + 1500
    ch5 forward = x * rpy + 1500       ch6 lateral = y * rpy + 1500
    ch7 camera pan 1500, ch8 camera tilt 1500, ch9 lights 1 = RC9_MIN, ch10 lights 2 = RC10_MIN (at boot), ch11 video
    switch 1100

in float32, converted to int16 (`numeric.float_to_int`: truncated toward zero, saturated to int32, then the low 16
bits) and only then clamped to 1100-1900. So a joystick at rest (x = y = r = 0, z = 500) puts
1500 on channels 1-8. Measured on the 4.5.3 SITL binary: gain 0.5 by default; x=400, y=-200, z=700, r=100 gave
1500, 1500, 1580, 1520, 1580, 1460, 1500, 1500, 1100, 1100, 1100; x=-1 gave 1499 on channel 5 (truncation); s=100,
t=-200 gave 1600 and 1300 on channels 1 and 2; a MANUAL_CONTROL replaced an RC_CHANNELS_OVERRIDE of 7-11.

ArduSub 4.7 made the lights and the video switch servo functions of their own (Lights1 181, Lights2 182, video switch
183: PR #29863, `SRV_Channel.h`), so its `transform_manual_control_to_rc_override` overrides channels 1-6 and the
camera mount's pan and tilt channels (RC7_OPTION 214, RC8_OPTION 213 by Sub's defaults, `Sub::load_parameters`):
1500 with no button held. Channels 9-11 are left alone (`rc_channels(..., firmware="4.7")` returns 8 values).
"""

from __future__ import annotations

import numpy as np

from sim_bridge.hardware.numeric import float_to_int

CHANNELS = 11
PWM_LOW, PWM_HIGH = 1100, 1900
CENTER = 1500
VIDEO_SWITCH = 1100
_F32 = np.float32


def joystick_gain(default: float, low: float, high: float, steps: int) -> float:
    """`Sub::init_joystick`: JS_GAIN_DEFAULT within JS_GAIN_MIN..MAX (or, if it lies outside and there are several
    JS_GAIN_STEPS, the step nearest the middle), then limited to 0.1..1."""
    steps = max(int(steps), 1)
    if steps == 1 or low - 0.01 < default < high + 0.01:
        gain = min(max(default, low), high)
    else:
        gain = low + (steps // 2 - 1) * (high - low) / (steps - 1)
    return float(_F32(min(max(gain, 0.1), 1.0)))


def _pwm(value) -> int:
    return min(max(float_to_int(value, 16), PWM_LOW), PWM_HIGH)


def rc_channels(x: int, y: int, z: int, r: int, s: int, t: int, gain: float, throttle_gain: float,
                lights: tuple[int, int], firmware: str = "4.5") -> list[int]:
    """The override values (channels 1..11 on 4.5, 1..8 on 4.7, us) of one MANUAL_CONTROL's axes."""
    rpy = _F32(0.4 * gain)
    throttle = _F32(0.8 * gain * throttle_gain)
    base = float_to_int(_F32(CENTER - 500 * throttle), 16)
    return [_pwm(s + CENTER), _pwm(t + CENTER),
            _pwm(_F32(z) * throttle + base), _pwm(_F32(r) * rpy + CENTER),
            _pwm(_F32(x) * rpy + CENTER), _pwm(_F32(y) * rpy + CENTER),
            CENTER, CENTER, *((lights[0], lights[1], VIDEO_SWITCH) if firmware == "4.5" else ())]
