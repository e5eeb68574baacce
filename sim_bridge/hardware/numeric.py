"""C's numeric conversions and float comparisons as ArduSub performs them on its flight controllers.

MAVLink hands the vehicle float32 command parameters and fixed-width integers; ArduPilot's handlers cast them with
plain C casts (e.g. `(uint32_t)packet.param1` in GCS_Common.cpp, `set_message_interval`) and compare floats with
AP_Math's `is_equal` / `is_zero`. A float cast to an integer type it does not fit is undefined in C; on the ARM
flight controllers a BlueROV2 flies (Pixhawk, Navigator) the conversion instruction (VCVT) truncates toward zero,
saturates at the 32-bit type's limits and gives 0 for NaN, and a narrower type keeps the low bits of that 32-bit
result. That is followed here. (ArduPilot's x86 SITL build traps such conversions and aborts instead: measured on
ArduSub 4.5.3 SITL with a 3.6e9 interval.)
"""

from __future__ import annotations

import math

import numpy as np

FLT_EPSILON = float(np.finfo(np.float32).eps)


def f32(value: float) -> float:
    """`value` rounded to a float32 (infinite beyond its range), as a Python float."""
    with np.errstate(over="ignore"):
        return float(np.float32(value))


def wrap(value: int, bits: int, signed: bool = True) -> int:
    """An integer converted to a narrower C integer type: its low `bits` bits, two's complement if `signed`."""
    low = value % (1 << bits)
    return low - (1 << bits) if signed and low >= 1 << (bits - 1) else low


def float_to_int(value: float, bits: int = 32, signed: bool = True) -> int:
    """`(intN_t)value` / `(uintN_t)value` for a float on ARM: truncated, saturated to 32 bits (NaN -> 0), then
    narrowed to `bits`."""
    if math.isnan(value):
        return 0
    low, high = (-(1 << 31), (1 << 31) - 1) if signed else (0, (1 << 32) - 1)
    whole = low if value <= low else high if value >= high else math.trunc(float(value))
    return wrap(whole, bits, signed)


def is_equal(a: float, b: float) -> bool:
    """AP_Math's `is_equal` for floats: closer than float32's epsilon (never for NaN)."""
    return abs(f32(a) - f32(b)) < FLT_EPSILON


def is_zero(a: float) -> bool:
    """AP_Math's `is_zero`: |a| below float32's epsilon."""
    return abs(a) < FLT_EPSILON
