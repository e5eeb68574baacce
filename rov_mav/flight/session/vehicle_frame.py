"""Is this the vehicle the vehicle file describes? Its frame (FRAME_CONFIG; the "Frame:" line of its banner where the
parameter cannot be read) and where its motors are (SERVO1..16_FUNCTION: motor k drives the outputs whose function
is 32 + k, SRV_Channel.h `get_motor_function`), held to the vehicle file's frame before anything is changed. Pure:
`flight.run.claim` reads the parameters and raises the refusal."""

from __future__ import annotations

from dataclasses import dataclass

from rov_mav.flight.session.vehicle_changes import PASSTHROUGH_BASE
from rov_mav.model.frames import MAX_MOTORS, MOTOR_FUNCTION_BASE, Frame, frames_by_string

OUTPUTS = 16                     # SERVO1..16
FUNCTION_NAMES = {0: "unassigned", 1: "RCPassThru", 6: "mount pan", 7: "mount tilt", 8: "mount roll",
                  59: "RCIN9", 60: "RCIN10", 181: "lights 1", 182: "lights 2", 183: "video switch"}


def function_name(function: int) -> str:
    """'Motor 3', 'RCIN2', 'mount tilt', or the number."""
    if MOTOR_FUNCTION_BASE < function <= MOTOR_FUNCTION_BASE + MAX_MOTORS:
        return f"Motor {function - MOTOR_FUNCTION_BASE}"
    if PASSTHROUGH_BASE < function <= PASSTHROUGH_BASE + 16:
        return f"RCIN{function - PASSTHROUGH_BASE}"
    return FUNCTION_NAMES.get(function, f"function {function}")


@dataclass(frozen=True)
class MotorOutputs:
    """Where each motor of the frame is: `outputs[k - 1]` is motor k's output (1-based). `stale` lists the outputs
    found on RCIN passthrough of their motor's channel where no output drives that motor (left so by a run that lost
    its link: they are the motor's output, to be restored to it)."""

    outputs: tuple[int, ...]
    stale: tuple[int, ...] = ()

    def name(self, motor: int) -> str:
        """SERVOn_FUNCTION of motor `motor` (1-based)."""
        return f"SERVO{self.outputs[motor - 1]}_FUNCTION"

    def names(self) -> list[str]:
        return [self.name(k) for k in range(1, len(self.outputs) + 1)]

    def describe(self) -> str:
        """'motors 1-8 on SERVO1-8' or 'motors 1-8 on SERVO9, 10, ...'."""
        n = len(self.outputs)
        if self.outputs == tuple(range(self.outputs[0], self.outputs[0] + n)):
            return f"motors 1-{n} on SERVO{self.outputs[0]}-{self.outputs[-1]}"
        return f"motors 1-{n} on SERVO" + ", ".join(map(str, self.outputs))


DEFAULT_OUTPUTS = MotorOutputs(tuple(range(1, MAX_MOTORS + 1)))   # before the vehicle is read: motor k on output k


def frame_refusal(found: Frame, expected: Frame, vehicle: str) -> str | None:
    """Why a vehicle of frame `found` is not the one the vehicle file (named `vehicle`, of frame `expected`)
    describes; None when it is."""
    if found.config == expected.config:
        return None
    return f"{found.describe()}: the vehicle file describes {vehicle} ({expected.label.upper()}, {expected.motors})"


def banner_frame(text: str, expected: Frame) -> Frame | None:
    """The frame a "Frame: <string>" banner line names: `expected` when its string is expected's, else the first
    frame of that string; None when no frame has it."""
    name = text.removeprefix("Frame:").strip()
    frames = frames_by_string(name)
    if not frames:
        return None
    return expected if expected in frames else frames[0]


def find_motors(functions: dict[int, int], frame: Frame, vehicle: str, passthrough: bool) -> MotorOutputs | str:
    """The outputs of `frame`'s motors among `functions` (output number -> SERVOn_FUNCTION), or why the run must not
    take them (a motor on no output or on two, a motor the frame does not have; with `passthrough`, another output on
    RC passthrough of a channel the run's overrides write, which would pass a thruster's command on)."""
    n = frame.motors
    def outputs_of(function: int) -> list[int]:
        return [j for j, f in sorted(functions.items()) if f == function]

    at = {k: outputs_of(MOTOR_FUNCTION_BASE + k) for k in range(1, MAX_MOTORS + 1)}
    rcin = {k: outputs_of(PASSTHROUGH_BASE + k) for k in range(1, MAX_MOTORS + 1)}
    stale = {k: rcin[k][0] for k in range(1, n + 1) if not at[k] and len(rcin[k]) == 1}
    problems = []
    if beyond := [k for k in range(n + 1, MAX_MOTORS + 1) if at[k]]:
        problems.append("motor " + ", ".join(f"{k} on SERVO{at[k][0]}" for k in beyond)
                        + f": more motors than {vehicle}'s {n}")
    if doubled := [k for k in range(1, n + 1) if len(at[k]) > 1]:
        problems.append("; ".join(f"motor {k} on " + " and ".join(f"SERVO{j}" for j in at[k]) for k in doubled))
    if missing := [k for k in range(1, n + 1) if not at[k] and k not in stale]:
        shown = [k for k in missing if k in functions]
        problems.append(f"motor {', '.join(map(str, missing))} on no output"
                        + (" (" + ", ".join(f"SERVO{k}_FUNCTION is {functions[k]}, {function_name(functions[k])}"
                                            for k in shown) + ")" if shown else "")
                        + f": {vehicle} has {n} thrusters")
    if passthrough:
        foreign = [(j, k) for k in range(1, MAX_MOTORS + 1) for j in rcin[k] if stale.get(k) != j]
        if foreign:
            problems.append(", ".join(f"SERVO{j}_FUNCTION is RCIN{k}" for j, k in foreign)
                            + ": that output would pass the run's thruster commands on")
    if problems:
        return "; ".join(problems)
    outputs = tuple(at[k][0] if at[k] else stale[k] for k in range(1, n + 1))
    return MotorOutputs(outputs, tuple(stale[k] for k in sorted(stale)))

