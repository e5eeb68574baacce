"""ArduSub's frames (FRAME_CONFIG): which motors each has and how its mixer weighs the six pilot axes.

From libraries/AP_Motors/AP_Motors6DOF.cpp, `AP_Motors6DOF::setup_motors` (the factor tables, identical in the
upstream version read and in the 4.7-era copies), its frame strings (`_frame_class_string`, printed as "Frame: ..."
by `GCS_MAVLINK_Sub::send_banner`) and `output_armed_stabilizing` (which of three mixer paths a frame takes), and
SRV_Channel.h `get_motor_function` (motor k drives the outputs whose SERVOn_FUNCTION is 33 + k - 1). The frame is
read once at boot (`Sub::init_rc_out`: FRAME_CONFIG is @RebootRequired). CUSTOM has no table of its own and takes
SIMPLEROV_3's; SIMPLEROV_4, SIMPLEROV_5 and any unknown value take the five-motor default table.

Factors per motor: (roll, pitch, yaw, throttle, forward, lateral), the mixer's axis order.
"""

from __future__ import annotations

from dataclasses import dataclass

MOTOR_FUNCTION_BASE = 32          # SERVOn_FUNCTION 32 + k = motor k (k = 1..8; motors 9-12 are 82-85)
MAX_MOTORS = 8                    # every Sub frame has at most 8

# mixer paths of `AP_Motors6DOF::output_armed_stabilizing`
SUMMED = "summed"                 # everything added, each motor clipped to [-1, 1]
VECTORED = "vectored"             # summed, forward limited on the thrusters that also push up (MOT_FV_CPLNG_K)
GROUPED = "grouped"               # vertical and horizontal groups each scaled down to fit, then added


@dataclass(frozen=True)
class Frame:
    """One FRAME_CONFIG: its number, ArduSub's frame string, the mixer path and the factors of motors 1..n."""

    config: int
    name: str
    mixer: str
    factors: tuple[tuple[float, float, float, float, float, float], ...]

    @property
    def motors(self) -> int:
        return len(self.factors)

    @property
    def label(self) -> str:
        """The FRAME_CONFIG parameter's label in lower case ('vectored_6dof'), as a vehicle file names the frame."""
        return CONFIG_NAMES.get(self.config, "unknown").lower()

    def describe(self) -> str:
        """'FRAME_CONFIG 1 (VECTORED, 6 motors)', with the parameter's own label for the frame."""
        return f"FRAME_CONFIG {self.config} ({self.label.upper()}, {self.motors} motors)"


_HORIZONTAL = ((0, 0, 1, 0, -1, 1), (0, 0, -1, 0, -1, -1), (0, 0, -1, 0, 1, 1), (0, 0, 1, 0, 1, -1))
_SIMPLE = ((0, 0, -1, 0, 1, 0), (0, 0, 1, 0, 1, 0))
_DEFAULT_TABLE = (*_SIMPLE, (1, 0, 0, -1, 0, 0), (-1, 0, 0, -1, 0, 0), (0, 0, 0, 0, 0, 1))
_SIMPLEROV_3 = (*_SIMPLE, (0, 0, 0, -1, 0, 0))

FRAMES = {f.config: f for f in (
    Frame(0, "BLUEROV1", SUMMED, ((0, 0, -1, 0, 1, 0), (0, 0, 1, 0, 1, 0), (-0.5, 0.5, 0, 0.45, 0, 0),
                                  (0.5, 0.5, 0, 0.45, 0, 0), (0, -1, 0, 1, 0, 0), (-0.25, 0, 0, 0, 0, 1))),
    Frame(1, "VECTORED", VECTORED, (*_HORIZONTAL, (1, 0, 0, -1, 0, 0), (-1, 0, 0, -1, 0, 0))),
    Frame(2, "VECTORED_6DOF", GROUPED, (*_HORIZONTAL, (1, -1, 0, -1, 0, 0), (-1, -1, 0, -1, 0, 0),
                                       (1, 1, 0, -1, 0, 0), (-1, 1, 0, -1, 0, 0))),
    Frame(3, "VECTORED_6DOF_90DEG", SUMMED, ((1, 1, 0, 1, 0, 0), (0, 0, 1, 0, 1, 0), (1, -1, 0, 1, 0, 0),
                                             (0, 0, 0, 0, 0, 1), (0, 0, 0, 0, 0, 1), (-1, 1, 0, 1, 0, 0),
                                             (0, 0, -1, 0, 1, 0), (-1, -1, 0, 1, 0, 0))),
    Frame(4, "SIMPLEROV_3", SUMMED, _SIMPLEROV_3),
    Frame(5, "DEFAULT", SUMMED, _DEFAULT_TABLE),
    Frame(6, "DEFAULT", SUMMED, _DEFAULT_TABLE),
    Frame(7, "SIMPLEROV_3", SUMMED, _SIMPLEROV_3),
)}
CONFIG_NAMES = {0: "BLUEROV1", 1: "VECTORED", 2: "VECTORED_6DOF", 3: "VECTORED_6DOF_90DEG", 4: "SIMPLEROV_3",
                5: "SIMPLEROV_4", 6: "SIMPLEROV_5", 7: "CUSTOM"}    # the FRAME_CONFIG parameter's own labels
HEAVY = FRAMES[2]                 # the BlueROV2 Heavy


def frame_of(config: int) -> Frame:
    """The frame ArduSub builds for FRAME_CONFIG `config` (an unknown value: the default five-motor table)."""
    if config in FRAMES:
        return FRAMES[config]
    return Frame(config, "DEFAULT", SUMMED, _DEFAULT_TABLE)


def frame_named(label: str) -> Frame:
    """A frame by its `Frame.label` ('vectored_6dof'); KeyError."""
    for frame in FRAMES.values():
        if frame.label == label:
            return frame
    raise KeyError(label)


def frames_by_string(banner_name: str) -> list[Frame]:
    """The frames whose "Frame: <name>" banner reads `banner_name` (several share a string)."""
    return [f for f in FRAMES.values() if f.name == banner_name]

