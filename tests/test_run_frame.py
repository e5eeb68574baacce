"""A run flies only the vehicle its vehicle file describes: the frame (FRAME_CONFIG) and where the motors are
(SERVO1..16_FUNCTION) are read before anything is changed, and a vehicle that is not the file's is refused in one
line, changing nothing. Against a bridge process told it is another vehicle (`--param`), watched by a station on
another link of the vehicle: it sees every PARAM_VALUE a PARAM_SET makes the vehicle send on every link, and every
HEARTBEAT's armed bit."""

from __future__ import annotations

import pytest
from run_helpers import (
    bridge_with_checker,
    checker,
    fresh,
    runner_against,
    servo_functions_16,
    short_mission,
    watch_run,
)

from rov_mav.flight.session.vehicle_frame import banner_frame, find_motors
from rov_mav.model.frames import FRAMES, HEAVY

HEAVY_FILE = "BlueROV2 Heavy"


@pytest.mark.parametrize("params, output, said", [
    (["FRAME_CONFIG=1"], (), f"FRAME_CONFIG 1 (VECTORED, 6 motors): the vehicle file describes {HEAVY_FILE} "
                             "(VECTORED_6DOF, 8)"),
    (["SERVO7_FUNCTION=0", "SERVO8_FUNCTION=7"], (),
     "motor 7, 8 on no output (SERVO7_FUNCTION is 0, unassigned, SERVO8_FUNCTION is 7, mount tilt)"),
    (["SERVO9_FUNCTION=33"], (), "motor 1 on SERVO1 and SERVO9"),
    (["FRAME_CONFIG=1"], ("--output", "motor-test"), "FRAME_CONFIG 1 (VECTORED, 6 motors)"),
    (["FRAME_CONFIG=1"], ("--controller", "ardusub-guided"), "FRAME_CONFIG 1 (VECTORED, 6 motors)"),
], ids=["standard-bluerov2", "mount-on-output-8", "motor-doubled", "motor-test", "guided"])
@pytest.mark.process
def test_another_vehicle_is_refused_in_one_line_and_left_untouched(tmp_path, params, output, said):
    mission = short_mission(tmp_path, goto_x=1.0, hold=1.0)
    bridge, port = bridge_with_checker(tmp_path, *[a for p in params for a in ("--param", p)])
    with bridge:
        gcs = checker(port)
        before = servo_functions_16(gcs)
        with runner_against(bridge, mission, *output) as run:
            written, armed = watch_run(gcs, run)
            code = run.wait()
        refusal = [line for line in run.output.splitlines() if "stopping: refusing to fly this vehicle" in line]
        assert code != 0 and len(refusal) == 1 and said in refusal[0], run.output
        assert "Nothing was changed on it" in refusal[0]
        assert written == [] and not armed, (written, armed)
        assert servo_functions_16(gcs) == before
        assert int(gcs.get_param("MAV_GCS_SYSID").param_value) == 255


@pytest.mark.process
def test_motors_moved_to_outputs_9_to_16_fly_and_only_those_outputs_are_touched(tmp_path):
    """A Heavy wired to outputs 9..16 (1..8 unassigned): the run switches SERVO9..16 to RCIN1..8 passthrough, flies
    and restores them; SERVO1..8 are never written and never pulse."""
    moved = [f"SERVO{n}_FUNCTION=0" for n in range(1, 9)] + [f"SERVO{n + 8}_FUNCTION={32 + n}" for n in range(1, 9)]
    mission = short_mission(tmp_path, goto_x=1.0, hold=1.0)
    bridge, port = bridge_with_checker(tmp_path, *[a for p in moved for a in ("--param", p)])
    with bridge:
        gcs = checker(port)
        before = servo_functions_16(gcs)
        assert before == [0] * 8 + list(range(33, 41))
        with runner_against(bridge, mission) as run:
            written, armed = watch_run(gcs, run)
            code = run.wait()
        assert code == 0 and "motors 1-8 on SERVO9-16" in run.output, run.output
        assert armed
        assert {w.split("=")[0] for w in written} <= {f"SERVO{n}_FUNCTION" for n in range(9, 17)} | {
            "MAV_GCS_SYSID_HI"}, written
        assert {f"SERVO{n + 8}_FUNCTION={50 + n}" for n in range(1, 9)} <= set(written)
        assert servo_functions_16(gcs) == before
        out = fresh(gcs, "SERVO_OUTPUT_RAW")
        assert [getattr(out, f"servo{n}_raw") for n in range(1, 9)] == [0] * 8
        assert [getattr(out, f"servo{n}_raw") for n in range(9, 17)] == [1500] * 8


@pytest.mark.process
def test_a_dry_run_reads_the_frame_and_outputs_and_says_them(tmp_path):
    mission = short_mission(tmp_path, goto_x=1.0, hold=1.0)
    bridge, port = bridge_with_checker(tmp_path)
    with bridge:
        gcs = checker(port)
        with runner_against(bridge, mission, "--dry-run") as run:
            written, armed = watch_run(gcs, run)
            code = run.wait()
    assert code == 0, run.output
    assert "frame: FRAME_CONFIG 2 (VECTORED_6DOF, 8 motors), motors 1-8 on SERVO1-8" in run.output
    assert written == [] and not armed


# -- the check itself, on every frame -------------------------------------------------------------------------


def heavy_outputs(**moved: int) -> dict[int, int]:
    functions = {n: 32 + n if n <= 8 else 0 for n in range(1, 17)}
    functions.update({int(k[1:]): v for k, v in moved.items()})
    return functions


def test_every_frame_but_the_heavys_has_another_motor_count_or_table():
    assert HEAVY.motors == 8 and all(f.factors != HEAVY.factors for f in FRAMES.values() if f is not HEAVY)


def test_find_motors_on_the_heavy():
    assert find_motors(heavy_outputs(), HEAVY, "H", passthrough=True).outputs == tuple(range(1, 9))
    # a run that lost its link left motor 3's output on RCIN3: taken as motor 3's, to restore
    stale = find_motors(heavy_outputs(s3=53), HEAVY, "H", passthrough=True)
    assert stale.outputs[2] == 3 and stale.stale == (3,)
    # an output passing channel 2 on (a gripper on RCIN2) would get thruster 2's commands through passthrough ...
    refused = find_motors(heavy_outputs(s11=52), HEAVY, "H", passthrough=True)
    assert refused == "SERVO11_FUNCTION is RCIN2: that output would pass the run's thruster commands on"
    # ... but not through the motor test, which names the motors
    assert find_motors(heavy_outputs(s11=52), HEAVY, "H", passthrough=False).outputs == tuple(range(1, 9))
    moved = find_motors(heavy_outputs(s2=0, s10=34), HEAVY, "H", True)
    assert moved.outputs == (1, 10, 3, 4, 5, 6, 7, 8)
    assert moved.describe() == "motors 1-8 on SERVO1, 10, 3, 4, 5, 6, 7, 8"
    assert find_motors(heavy_outputs(s4=0), HEAVY, "H", True) == \
        "motor 4 on no output (SERVO4_FUNCTION is 0, unassigned): H has 8 thrusters"


def test_find_motors_refuses_more_motors_than_the_file_has():
    """A vehicle file of a six-motor frame (none ships yet) against a Heavy's outputs."""
    assert find_motors(heavy_outputs(), FRAMES[1], "V", True) == \
        "motor 7 on SERVO7, 8 on SERVO8: more motors than V's 6"


def test_the_banner_names_the_frame_where_frame_config_cannot_be_read():
    """`GCS_MAVLINK_Sub::send_banner`'s "Frame: <string>": several frames share a string (SIMPLEROV_3 is also CUSTOM's,
    DEFAULT SimpleROV-4's and -5's); the expected frame is taken when its string is the one said."""
    assert banner_frame("Frame: VECTORED_6DOF", HEAVY) is HEAVY
    assert banner_frame("Frame: VECTORED", HEAVY) is FRAMES[1]
    assert banner_frame("Frame: SIMPLEROV_3", FRAMES[7]) is FRAMES[7]
    assert banner_frame("Frame: SOMETHING_NEW", HEAVY) is None
