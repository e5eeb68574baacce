"""MAVLink 2 signing end to end: `rov-mav run` and `rov-mav sim-bridge` with a key, stations with the wrong key or
none, and MAVProxy's own `signing` commands as an independent client. Every bridge here listens on link 0 (ArduPilot's
channel 0, which takes unsigned traffic: the checker's) and on further links that do not."""

from __future__ import annotations

import re
import time

import pytest
from run_helpers import (
    RunnerProcess,
    armed,
    assert_left_safe,
    checker,
    free_port,
    servo_functions,
    short_mission,
)
from bridge_helpers import MAVPROXY, Console
from bridge_helpers import BridgeProcess, Gcs

from rov_mav.cli import main as rov_mav
from rov_mav.signing import (
    TICKS_PER_SECOND,
    Rejections,
    check_signature_first,
    key_from_passphrase,
    timestamp,
)

PASSPHRASE = "sesame"
IGNORED = 3.0            # wall s a request goes unanswered before we say the vehicle ignored it
MAVPROXY_COMPID = 230    # MAVProxy's default --source-component


def _signing_bridge(workdir, *args: str, speedup: float = 10.0) -> tuple[BridgeProcess, list[int]]:
    """A bridge with link 0 on BridgeProcess.port (the checker's) and two more links, whose ports are returned."""
    ports = [free_port(), free_port()]
    listens = [a for p in ports for a in ("--listen", f"udpin:127.0.0.1:{p}")]
    return BridgeProcess(workdir, *listens, *args, speedup=speedup), ports


def _station(port: int, key: bytes | None, speedup: float = 10.0) -> Gcs:
    """A pymavlink station as sysid 255 (the GCS sysid), component 190 (the runner's), signing with `key`."""
    station = Gcs(port, speedup=speedup)
    if key is not None:
        station.conn.setup_signing(key, sign_outgoing=True)
    return station


def _answers(station: Gcs, name: str = "FS_GCS_TIMEOUT") -> float | None:
    """The vehicle's answer to a PARAM_REQUEST_READ, or None if it ignored the station for IGNORED s."""
    try:
        return station.request(lambda: station.send("param_request_read", 1, 1, name.encode(), -1), "PARAM_VALUE",
                               lambda m: m.param_id == name, timeout=IGNORED).param_value
    except AssertionError:
        return None


# -- keys ----------------------------------------------------------------------------------------------------


def test_a_passphrase_gives_mavproxys_key():
    from MAVProxy.modules.mavproxy_signing import SigningModule

    assert key_from_passphrase(PASSPHRASE) == SigningModule.passphrase_to_key(None, PASSPHRASE)


@pytest.mark.parametrize("content", [b"", b"x" * 31, b"x" * 33, b"00" * 32 + b"\n", None])
def test_a_key_file_of_anything_but_32_bytes_is_one_line_and_exit_2(tmp_path, capsys, content):
    key = tmp_path / "key"
    if content is None:
        key.mkdir()
    else:
        key.write_bytes(content)
    mission = short_mission(tmp_path)
    for argv in (["run", str(mission), "--signing-key", str(key)], ["sim-bridge", "--signing-key", str(key)]):
        assert rov_mav(argv) == 2
        err = capsys.readouterr().err.strip()
        assert "\n" not in err and err.startswith(f"rov-mav {argv[0]}: error: --signing-key") and str(key) in err, err


@pytest.mark.parametrize("passphrase", ["", "sésame"])
def test_an_empty_or_non_ascii_passphrase_is_refused(tmp_path, capsys, passphrase):
    assert rov_mav(["run", str(short_mission(tmp_path)), "--signing-passphrase", passphrase]) == 2
    assert capsys.readouterr().err.strip().startswith("rov-mav run: error: --signing-passphrase")


def test_a_frame_with_the_wrong_key_does_not_lock_the_genuine_stream_out():
    from pymavlink.dialects.v20 import ardupilotmega as mavlink

    key = key_from_passphrase(PASSPHRASE)

    def sender(secret: bytes, ts: int):
        mav = mavlink.MAVLink(None, 255, 190)
        mav.signing.secret_key, mav.signing.sign_outgoing, mav.signing.timestamp = secret, True, ts
        return mav

    now = timestamp(time.time())
    genuine, forger = sender(key, now), sender(bytes(32), now + 3600 * TICKS_PER_SECOND)  # same stream, an hour on
    receiver = mavlink.MAVLink(None)
    receiver.robust_parsing = True
    receiver.signing.secret_key = key
    check_signature_first(receiver)
    rejections = Rejections()
    kinds = []
    for mav in (genuine, forger, genuine, genuine):
        for msg in receiver.parse_buffer(mav.heartbeat_encode(6, 8, 0, 0, 0).pack(mav)):
            kinds.append(msg.get_type())
            rejections.note(msg)
    assert kinds == ["HEARTBEAT", "BAD_DATA", "HEARTBEAT", "HEARTBEAT"]
    assert rejections.count == 1 and rejections.first.signed and rejections.first.sysid == 255


def test_a_setup_signing_timestamp_near_2_to_the_64_wraps_as_a_uint64():
    """Found by tests/test_bridge_fuzz.py: the loaded timestamp (stored + a minute) and every frame's increment
    overflowed pymavlink's 64-bit pack, in the bridge's telemetry loop, and killed it."""
    from pymavlink.dialects.v20 import ardupilotmega as mavlink

    from sim_bridge.transport.link import Link
    from sim_bridge.gcs.signing import VehicleSigning

    link = Link(f"udpout:127.0.0.1:{free_port()}", 1, 1)
    try:
        signing = VehicleSigning(None, time.time())
        signing.attach([link])
        signing.setup(bytes(range(32)), 2**64 - 1, "a test")
        for _ in range(3):
            link.send(mavlink.MAVLink_heartbeat_message(12, 3, 81, 19, 3, 3))
        assert 0 < link.signing.timestamp < 2**64
    finally:
        link.close()


# -- the runner against a signing vehicle --------------------------------------------------------------------


def _intrude(port: int, key: bytes | None, seconds: float) -> int:
    """As the GCS sysid, on its own link, at 20 Hz for `seconds`: full-stick overrides, disarm, a parameter change
    and an order to turn signing off. With a key, first a HEARTBEAT under every link id with a timestamp an hour
    ahead: one of them is the run's signing stream, which it would take over if a wrong signature still moved the
    stream's timestamp. Returns the frames sent."""
    station = _station(port, key)
    sent = 0
    if key is not None:
        station.conn.mav.signing.timestamp = timestamp(time.time()) + 3600 * TICKS_PER_SECOND
        for link_id in range(256):
            station.conn.mav.signing.link_id = link_id
            station.heartbeat()
            sent += 1
    end = time.monotonic() + seconds
    try:
        while time.monotonic() < end:
            station.heartbeat()
            station.rc_override([1900] * 8)
            station.send("command_long", 1, 1, 400, 0, 0, 21196, 0, 0, 0, 0, 0)
            station.send("param_set", 1, 1, b"FS_GCS_TIMEOUT", 9.0, 9)
            station.send("setup_signing", 1, 1, [0] * 32, 0)
            sent += 5
            time.sleep(0.05)
    finally:
        station.close()
    return sent


@pytest.mark.process
def test_a_signed_run_flies_while_stations_with_the_wrong_key_or_none_are_ignored(tmp_path):
    mission = short_mission(tmp_path, hold=20.0)
    bridge, (run_port, intruder_port) = _signing_bridge(tmp_path, "--start-depth", "1", "--signing-passphrase",
                                                        PASSPHRASE)
    with bridge:
        gcs = checker(bridge.port)            # link 0 takes unsigned traffic, as ArduPilot's channel 0 (USB)
        try:
            with RunnerProcess("--target", f"udpout:127.0.0.1:{run_port}", str(mission), "--signing-passphrase",
                               PASSPHRASE, "--heartbeat-timeout", "60", "--rerun", "off") as run:
                run.wait_for("armed in MANUAL")
                sent = _intrude(intruder_port, key_from_passphrase("not sesame"), 1.5)
                sent += _intrude(intruder_port, None, 1.5)
                assert run.wait() == 0, run.output
            assert_left_safe(gcs)
            assert gcs.get_param("FS_GCS_TIMEOUT").param_value == 5.0
        finally:
            gcs.close()
    assert "completed" in run.output and "handed over" not in run.output, run.output
    dropped = re.search(r"frames dropped for their signature: link 2: (\d+)$", bridge.output, re.MULTILINE)
    assert dropped and 0.5 * sent <= int(dropped.group(1)) <= sent, (sent, bridge.output)   # UDP may lose some
    assert "signing turned off" not in bridge.output


@pytest.mark.process
@pytest.mark.parametrize("vehicle_key", [None, "another passphrase"])
def test_a_run_with_a_key_refuses_a_vehicle_that_does_not_sign_with_it(tmp_path, vehicle_key):
    args = ("--signing-passphrase", vehicle_key) if vehicle_key else ()
    bridge, (run_port, _) = _signing_bridge(tmp_path, *args)
    with bridge:
        gcs = checker(bridge.port)
        try:
            with RunnerProcess("--target", f"udpout:127.0.0.1:{run_port}", str(short_mission(tmp_path)),
                               "--signing-passphrase", PASSPHRASE, "--rerun", "off") as run:
                assert run.wait() == 1, run.output
            assert not armed(gcs) and servo_functions(gcs) == list(range(33, 41))
        finally:
            gcs.close()
    refusals = [line for line in run.output.splitlines() if "stopping: refusing" in line]
    how = "unsigned" if vehicle_key is None else "signed with another key"
    assert len(refusals) == 1 and f"not signed with our key (the first: HEARTBEAT from 1/1, {how}" in refusals[0], \
        run.output
    assert sum("ignoring MAVLink not signed" in line for line in run.output.splitlines()) == 1, run.output
    ignored = re.search(r"signing: (\d+) message\(s\) not signed with our key ignored", run.output)
    assert ignored and int(ignored.group(1)) >= 3, run.output
    assert "no ArduSub vehicle was taken over" in run.output


# -- MAVProxy's signing commands -----------------------------------------------------------------------------


@pytest.mark.process
def test_mavproxy_signing_key_and_setup_against_the_bridge(tmp_path):
    # real time: MAVProxy sends its GCS heartbeat at 1 Hz of wall time
    bridge, (mavproxy_port, station_port) = _signing_bridge(tmp_path, "--signing-passphrase", PASSPHRASE,
                                                            speedup=1.0)
    with bridge:
        gcs = checker(bridge.port)
        console = Console([MAVPROXY, f"--master=udpout:127.0.0.1:{mavproxy_port}", f"--state-basedir={tmp_path}"],
                          tmp_path / "mavproxy.out", tmp_path)
        try:
            console.expect("Detected vehicle 1:1")          # it reads our signed frames; we drop its unsigned ones
            console.send("arm throttle")
            time.sleep(IGNORED)
            assert not armed(gcs)
            console.send("signing key " + PASSPHRASE)       # the key from the passphrase, as the bridge's
            console.expect("Setup signing key")
            console.poll("param fetch FS_GCS_TIMEOUT", "FS_GCS_TIMEOUT = 5")
            console.poll("arm throttle", "ARMED")
            assert armed(gcs)
            console.send("signing setup other")             # refused while armed, as ArduSub
            console.expect("Won't setup signing when armed")
            console.send("signing key " + PASSPHRASE)
            console.poll("disarm", "DISARMED")
            console.send("signing setup newphrase")         # SETUP_SIGNING, signed with the current key
            console.expect("Sent secret_key")
            for key, answered in ((key_from_passphrase("newphrase"), True), (key_from_passphrase(PASSPHRASE), False),
                                  (None, False)):
                station = _station(station_port, key, speedup=1.0)
                try:
                    assert (_answers(station) is not None) == answered, key
                finally:
                    station.close()
            console.send("signing remove")                  # an all-zero key: signing off
            console.expect("Removed signing")
            station = _station(station_port, None, speedup=1.0)
            try:
                assert _answers(station) == 5.0
            finally:
                station.close()
        finally:
            console.close("exit")
            gcs.close()
    assert f"signing key set by SETUP_SIGNING from 255/{MAVPROXY_COMPID} on link 1" in bridge.output, bridge.output
    assert "signing turned off by SETUP_SIGNING" in bridge.output, bridge.output
