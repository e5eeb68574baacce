"""The run against ArduSub 4.7's throttle-centred arming check (`AP_Arming_Sub::arm`): it arms with the neutral it
holds on every channel; a vehicle whose RC3_TRIM is off that neutral refuses, and the run says the vehicle's words
and leaves it as found. Against a bridge process, watched from another link."""

from __future__ import annotations

import pytest
from run_helpers import bridge_with_checker, checker, runner_against, servo_functions_16, short_mission, watch_run

pytestmark = pytest.mark.process      # starts a process or the bridge (tests/conftest.py)


def test_a_refused_arming_is_quoted_and_the_vehicle_left_as_found(tmp_path):
    mission = short_mission(tmp_path, goto_x=1.0, hold=1.0)
    bridge, port = bridge_with_checker(tmp_path, "--param", "RC3_TRIM=1600")
    with bridge:
        gcs = checker(port)
        before = servo_functions_16(gcs)
        with runner_against(bridge, mission) as run:
            written, armed = watch_run(gcs, run)
            code = run.wait()
        assert code != 0 and not armed, run.output
        assert "arming failed: the vehicle refused it: PreArm: Throttle not centered/close to trim" in run.output
        assert servo_functions_16(gcs) == before
        assert {w.split("=")[0] for w in written} <= {f"SERVO{n}_FUNCTION" for n in range(1, 9)}   # and back
