"""ArduPilot's own ArduSub SITL for end-to-end tests, found through ARDUSUB_SITL (the launcher is
`rov_mav.sitl`, shared with tools/); without it the tests that need it are skipped with the reason."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from rov_mav import sitl as launcher

SPEEDUP = 4.0                 # a 2-core machine shared with the runner holds this
BOOT_WAIT = launcher.BOOT_WAIT


def sitl_binary() -> Path:
    """The SITL binary, or skip with the reason (CI sets ARDUSUB_SITL, so it runs these)."""
    try:
        binary = launcher.binary_from_environment()
    except launcher.SitlError as exc:
        pytest.fail(str(exc))
    if binary is None:
        pytest.skip(f"{launcher.SITL_ENV} is not set: point it at an ArduSub SITL binary (ArduPilot's "
                    "build/sitl/bin/ardusub) to run the tests against real ArduSub")
    return binary


class Sitl(launcher.Sitl):
    """The launcher on the binary ARDUSUB_SITL names, at the tests' speedup."""

    def __init__(self, workdir: Path, serial0: str | None = None, speedup: float = SPEEDUP):
        super().__init__(sitl_binary(), workdir, speedup, serial0=serial0)


class Checker:
    """An independent pymavlink client on a SITL TCP port, as sysid 200 (neither drives nor masks a GCS)."""

    def __init__(self, port: int):
        from pymavlink import mavutil

        self.mavlink = mavutil.mavlink
        self.conn = mavutil.mavlink_connection(f"tcp:127.0.0.1:{port}", source_system=200, source_component=190,
                                               autoreconnect=True)
        self.conn.wait_heartbeat(timeout=BOOT_WAIT)

    def fresh(self, kind: str, timeout: float = 10.0):
        """The next `kind` after everything queued was dropped (asked for once a second with REQUEST_MESSAGE)."""
        while self.conn.recv_match(blocking=False) is not None:
            pass
        deadline = time.monotonic() + timeout
        msg_id = getattr(self.mavlink, f"MAVLINK_MSG_ID_{kind}")
        while time.monotonic() < deadline:
            if kind != "HEARTBEAT":
                self.conn.mav.command_long_send(1, 1, self.mavlink.MAV_CMD_REQUEST_MESSAGE, 0, msg_id,
                                                0, 0, 0, 0, 0, 0)
            msg = self.conn.recv_match(type=kind, blocking=True, timeout=1.0)
            if msg is not None and msg.get_srcSystem() == 1:
                return msg
        raise AssertionError(f"no {kind} from SITL within {timeout} s")

    def param(self, name: str) -> float:
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline:
            self.conn.mav.param_request_read_send(1, 1, name.encode(), -1)
            msg = self.conn.recv_match(type="PARAM_VALUE", blocking=True, timeout=1.0)
            if msg is not None and msg.param_id == name:
                return msg.param_value
        raise AssertionError(f"SITL did not report {name}")

    def achieved_speedup(self, wall: float = 3.0) -> float:
        """Simulated seconds per wall second over `wall` s, from SYSTEM_TIME.time_boot_ms."""
        first = self.fresh("SYSTEM_TIME")
        t0 = time.monotonic()
        time.sleep(wall)
        last = self.fresh("SYSTEM_TIME")
        return (last.time_boot_ms - first.time_boot_ms) / 1e3 / (time.monotonic() - t0)

    def wait_for_position(self, timeout: float) -> None:
        """Until the EKF has a position (LOCAL_POSITION_NED answers)."""
        self.fresh("LOCAL_POSITION_NED", timeout)

    def armed(self) -> bool:
        return bool(self.fresh("HEARTBEAT").base_mode & self.mavlink.MAV_MODE_FLAG_SAFETY_ARMED)

    def servo_outputs(self) -> list[int]:
        msg = self.fresh("SERVO_OUTPUT_RAW")
        return [getattr(msg, f"servo{n}_raw") for n in range(1, 9)]

    def servo_functions(self) -> list[int]:
        return [int(self.param(f"SERVO{n}_FUNCTION")) for n in range(1, 9)]

    def assert_left_safe(self) -> None:
        assert not self.armed()
        assert self.servo_outputs() == [1500] * 8
        assert self.servo_functions() == list(range(33, 41))

    def close(self) -> None:
        self.conn.close()
