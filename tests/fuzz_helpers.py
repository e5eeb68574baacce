"""Fuzzing the built-in vehicle over real sockets: a bridge process with several links,
`sim_bridge.transport.fuzz.Traffic`
written to them, and an independent check that the vehicle came through it (used by tests/test_bridge_fuzz.py and
tools/fuzz_bridge.py).

Link 0 (the bridge's first udpin) belongs to the checker, a pymavlink station as sysid 200; the traffic goes to the
other links, UDP and TCP. Every BATCH chunks the sender waits until the bridge's side holds every TCP byte sent, then
for the vehicle to answer a TIMESYNC on link 0: the bridge reads its links in order on every pass, so everything sent
before that request is then being read, and the kernel never has to drop a datagram for want of buffer space. The
traffic may ask a link for every message every millisecond (as a station may: the vehicle then sends each at most
once per 2.5 ms main-loop step, and its simulated clock slows if the machine cannot keep up), so the checks avoid
streams: messages are requested, and intervals read with a probe that skips everything else.
"""

from __future__ import annotations

import fcntl
import math
import re
import socket
import struct
import termios
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

from run_helpers import CHECKER_SYSID, SPEEDUP
from bridge_helpers import RETRY, WAIT, BridgeProcess, Gcs, free_port, mavutil

from sim_bridge.autopilot.ardusub import MOTOR1, SUPPORTED_MODES
from sim_bridge.transport.fuzz import SIGNATURE_LEN, SIGNED, STX_V1, STX_V2, Traffic
from sim_bridge.autopilot.params import Params
from sim_bridge.gcs.telemetry import NAME_OF_ID

mav = mavutil.mavlink
LINKS = ("udp", "tcp", "udp", "tcp")           # the fuzzed links: 1..4 (a fifth link shares the fourth's rates)
BATCH = 100
EVERY_TYPE_PASSES = 2        # every type sent once more, twice over: a frame of the first pass that reboots the vehicle
                             # (a fuzzed COMMAND_LONG) drops the TCP links with what was still on its way
EVERY_TYPE_GROUP = 25        # frames between two syncs in those passes: no burst outruns a busy vehicle's UDP buffer
FLUSH = 280                                     # bytes: longer than any MAVLink frame
SERVOS = 16
INT_LIMITS = {mav.MAV_PARAM_TYPE_INT8: (-2**7, 2**7 - 1), mav.MAV_PARAM_TYPE_INT16: (-2**15, 2**15 - 1),
              mav.MAV_PARAM_TYPE_INT32: (-2**31, 2**31 - 1)}
MAX_DISTANCE = 1e4                              # m from the origin: anything beyond is a runaway state
COUNTERS = re.compile(r"sim-bridge: (\d+) messages received \((\d+) types\), (\d+) handler errors")


def fuzz_param_names() -> tuple[str, ...]:
    """The vehicle's parameter names for the traffic's PARAM_* messages, without the simulator's own SIM_* controls
    (pace and battery: changing them is steering the test rig, not the vehicle) and MAV_OPTIONS (its bit 0 makes the
    vehicle deaf to every sysid but its GCS's, the checker's included: that locks the rig out, as intended)."""
    return tuple(spec.name for spec in Params().specs if not spec.name.startswith("SIM_") and
                 spec.name != "MAV_OPTIONS")


def fuzzed_bridge(workdir: Path, speedup: float = SPEEDUP) -> tuple[BridgeProcess, list[tuple[str, int]]]:
    """A bridge process listening on the checker's udpin (BridgeProcess.port) and on one port per entry of LINKS."""
    links = [(kind, free_port(socket.SOCK_DGRAM if kind == "udp" else socket.SOCK_STREAM)) for kind in LINKS]
    args = [a for kind, port in links for a in ("--listen", f"{kind}in:127.0.0.1:{port}")]
    return BridgeProcess(workdir, *args, speedup=speedup), links


class Sender:
    """Sockets to the fuzzed links; replies are read and dropped. A TCP link the bridge closed (it drops a client
    that lets its replies pile up, and every client when the traffic reboots it) is reconnected and counted."""

    def __init__(self, links: list[tuple[str, int]]):
        self.links = links
        self.socks: list[socket.socket] = [self._open(kind, port) for kind, port in links]
        self.reconnects = 0

    @staticmethod
    def _open(kind: str, port: int) -> socket.socket:
        if kind == "udp":
            sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            sock.connect(("127.0.0.1", port))
        else:
            sock = socket.create_connection(("127.0.0.1", port), timeout=WAIT)
        sock.setblocking(False)
        return sock

    def send(self, index: int, data: bytes) -> None:
        sock = self.socks[index]
        try:
            if self.links[index][0] == "udp":
                sock.send(data)
            else:
                sock.settimeout(WAIT)              # the bridge reads every pass: a full buffer drains quickly
                sock.sendall(data)
                sock.setblocking(False)
        except (ConnectionError, BlockingIOError):
            self._reconnect(index)

    def wait_sent(self) -> None:
        """Until the kernel has handed every byte written to a TCP link over to the bridge's side (a slow bridge's
        full receive window keeps them here, and a TIMESYNC answered meanwhile would not cover them)."""
        deadline = time.monotonic() + WAIT
        for index, (kind, _) in enumerate(self.links):     # drain() may reconnect: read the socket afresh
            while kind == "tcp" and _unsent(self.socks[index]) and time.monotonic() < deadline:
                self.drain()
                time.sleep(0.002)

    def drain(self) -> None:
        for index, sock in enumerate(self.socks):
            while True:
                try:
                    if not sock.recv(65536) and self.links[index][0] == "tcp":
                        self._reconnect(index)
                        break
                except (BlockingIOError, InterruptedError):
                    break
                except ConnectionError:              # UDP: ICMP unreachable of an earlier datagram; TCP: reset
                    if self.links[index][0] == "tcp":
                        self._reconnect(index)
                        break

    def _reconnect(self, index: int) -> None:
        self.socks[index].close()
        self.socks[index] = self._open(*self.links[index])
        self.reconnects += 1

    def close(self) -> None:
        for sock in self.socks:
            sock.close()


def _unsent(sock: socket.socket) -> int:
    """Bytes in a TCP socket's send queue not yet taken by the peer (Linux SIOCOUTQ)."""
    return struct.unpack("i", fcntl.ioctl(sock.fileno(), termios.TIOCOUTQ, b"\0" * 4))[0]


@dataclass
class FuzzReport:
    """What was sent: chunks by kind, well-formed messages by type, wall time, TCP reconnections."""

    chunks: int = 0
    kinds: Counter = field(default_factory=Counter)
    types: Counter = field(default_factory=Counter)
    seconds: float = 0.0
    reconnects: int = 0

    @property
    def messages(self) -> int:
        return sum(self.types.values())


def fuzz(links: list[tuple[str, int]], checker: Gcs, chunks: int, seed: int, progress=None) -> FuzzReport:
    """Send `chunks` chunks of seeded traffic, each on a link chosen at random, pacing on `checker`'s TIMESYNC
    (`progress(report)` after every BATCH chunks). Then a sweep: FLUSH zero bytes on every link (ending whatever
    frame a broken chunk left open) and one well-formed message of every type, so that each type reaches the
    vehicle whole at least once whatever the broken frames before it swallowed."""
    traffic = Traffic(seed, param_names=fuzz_param_names())
    sender = Sender(links)
    report = FuzzReport()
    start = time.monotonic()

    def batch_done(k: int) -> None:
        sender.drain()
        sender.wait_sent()
        sync(checker, k)
        report.chunks, report.seconds = k, time.monotonic() - start
        report.kinds, report.types = traffic.sent_kinds, traffic.sent_types

    try:
        for k in range(1, chunks + 1):
            sender.send(traffic.rng.randrange(len(links)), traffic.chunk().data)
            if k % BATCH == 0:
                batch_done(k)
                if progress is not None:
                    progress(report)
        batch_done(chunks)
        for index in range(len(links)):
            sender.send(index, bytes(FLUSH))
        last = "SETUP_SIGNING"          # it may give the vehicle a key, after which unsigned frames are dropped
        for _ in range(EVERY_TYPE_PASSES):
            for index, name in enumerate(sorted(set(traffic.classes) - {last}) + [last]):
                if name == last or index % EVERY_TYPE_GROUP == 0:
                    batch_done(chunks)  # everything before read first (the vehicle reads its links in order)
                sender.send(index % len(links), traffic.frame(name))
                traffic.sent_types[name] += 1
            batch_done(chunks)
        sync(checker, chunks + 1)       # answered after the pass that read it: signed if it set a key
    finally:
        report.reconnects = sender.reconnects
        sender.close()
    return report


def sync(checker: Gcs, token: int) -> None:
    """Until the vehicle answers a TIMESYNC request on the checker's link. The checker first stops its link's
    streams, as a ground station sets the rates it wants, in case the traffic's PARAM_SETs raised them. If the answer
    is signed, the traffic's SETUP_SIGNING gave the vehicle a key (as it would ArduSub, disarmed), and the fuzzed
    links' unsigned frames would all be dropped from then on: the checker, on link 0 (ArduPilot's USB channel, which
    takes unsigned frames), turns signing off again, as an operator with a cable would. (The vehicle answers link 0
    before it reads the others in the same pass: a key set by the batch just sent shows in the next answer.)"""
    checker.send("request_data_stream", 1, 1, mav.MAV_DATA_STREAM_ALL, 0, 0)
    answer = checker.request(lambda: checker.send("timesync", 0, token), "TIMESYNC",
                             lambda m: m.ts1 == token and m.get_srcSystem() == 1)
    if answer.get_header().incompat_flags & SIGNED:      # pymavlink's get_signed() is for checked signatures
        checker.send("setup_signing", 1, 1, [0] * 32, 0)
        sync(checker, token + 1)


# -- the checks --------------------------------------------------------------------------------------------------


def check_vehicle(bridge: BridgeProcess, checker: Gcs, links: list[tuple[str, int]]) -> list[str]:
    """Everything wrong with the vehicle after the traffic, one line each (empty: it came through). Leaves it
    disarmed with its safety switch off."""
    problems: list[str] = []
    if bridge.proc.poll() is not None:
        return [f"the bridge process exited with status {bridge.proc.returncode}"]
    try:
        problems += _answers(checker)
        params = read_all_params(checker)
        problems += _parameters(params) + _state(checker) + _outputs(checker, params)
    except AssertionError as exc:
        problems.append(f"the vehicle stopped answering the checker: {exc}")
    for kind, port in links:
        try:
            problems += _intervals(kind, port)
        except AssertionError as exc:
            problems.append(f"intervals on {kind} link {port}: {exc}")
    return problems


def _answers(checker: Gcs) -> list[str]:
    """A heartbeat, a parameter read and acknowledged commands; then disarmed, safety off, in a mode it has."""
    checker.recv("HEARTBEAT", cond=lambda m: m.get_srcSystem() == 1)
    checker.get_param("FS_GCS_ENABLE")
    problems = []
    for name, params in (("disarm", (mav.MAV_CMD_COMPONENT_ARM_DISARM, 0)),
                         ("safety off", (mav.MAV_CMD_DO_SET_MODE, mav.MAV_MODE_FLAG_DECODE_POSITION_SAFETY, 0)),
                         ("request AUTOPILOT_VERSION", (mav.MAV_CMD_REQUEST_MESSAGE,
                                                        mav.MAVLINK_MSG_ID_AUTOPILOT_VERSION))):
        result = checker.command(*params).result
        if result != mav.MAV_RESULT_ACCEPTED:
            problems.append(f"{name}: MAV_RESULT {result}")
    checker.drop_queued()
    hb = checker.recv("HEARTBEAT", cond=lambda m: m.get_srcSystem() == 1)      # one sent after the disarm
    if hb.base_mode & mav.MAV_MODE_FLAG_SAFETY_ARMED:
        problems.append(f"still armed after a disarm (base_mode {hb.base_mode})")
    if hb.custom_mode not in SUPPORTED_MODES or not hb.base_mode & mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
        problems.append(f"HEARTBEAT mode {hb.base_mode}/{hb.custom_mode} is not one the vehicle has")
    if hb.system_status not in (mav.MAV_STATE_STANDBY, mav.MAV_STATE_CRITICAL):
        problems.append(f"disarmed but system_status {hb.system_status}")
    return problems


def read_all_params(checker: Gcs) -> dict[str, object]:
    """Every PARAM_VALUE of a PARAM_REQUEST_LIST (missing ones read again by index)."""
    first = checker.request(lambda: checker.send("param_request_list", 1, 1), "PARAM_VALUE",
                            lambda m: m.get_srcSystem() == 1)
    values = {first.param_index: first}
    for m in checker.collect(2.0, ["PARAM_VALUE"]):
        values.setdefault(m.param_index, m)
    for index in set(range(first.param_count)) - set(values):
        values[index] = checker.request(lambda i=index: checker.send("param_request_read", 1, 1, b"", i),
                                        "PARAM_VALUE", lambda m, i=index: m.param_index == i)
    return {m.param_id: m for i, m in values.items() if i < first.param_count}


def _parameters(params: dict[str, object]) -> list[str]:
    """Every parameter finite and within its type; as many as the vehicle has."""
    problems = [f"{len(params)} parameters listed, {len(Params())} expected"] if len(params) != len(Params()) else []
    for name, m in params.items():
        value, limits = m.param_value, INT_LIMITS.get(m.param_type)
        if not math.isfinite(value):
            problems.append(f"parameter {name} = {value}")
        elif limits is not None and not (value == int(value) and limits[0] <= value <= limits[1]):
            problems.append(f"parameter {name} = {value} does not fit its type {m.param_type}")
    return problems


def _state(checker: Gcs) -> list[str]:
    """Attitude, position, velocity and battery finite, the vehicle near the origin, angles within ±pi."""
    problems = []
    for kind in ("ATTITUDE", "LOCAL_POSITION_NED", "GLOBAL_POSITION_INT", "SYS_STATUS", "BATTERY_STATUS"):
        m = requested(checker, kind)
        numbers = [v for v in m.to_dict().values() if isinstance(v, float)]
        if not all(math.isfinite(v) for v in numbers):
            problems.append(f"{kind} not finite: {m}")
        if kind == "ATTITUDE" and not all(abs(a) <= math.pi + 1e-6 for a in (m.roll, m.pitch, m.yaw)):
            problems.append(f"attitude beyond ±pi: {m}")
        if kind == "LOCAL_POSITION_NED" and math.dist((m.x, m.y, m.z), (0, 0, 0)) > MAX_DISTANCE:
            problems.append(f"vehicle {math.dist((m.x, m.y, m.z), (0, 0, 0)):.0f} m from the origin")
    return problems


def _outputs(checker: Gcs, params: dict[str, object]) -> list[str]:
    """Disarmed with the safety off: every output routed to a motor neutral, every unassigned one silent."""
    functions = {n: int(params[f"SERVO{n}_FUNCTION"].param_value) for n in range(1, SERVOS + 1)}
    m = requested(checker, "SERVO_OUTPUT_RAW")
    problems = []
    for n, function in functions.items():
        value = getattr(m, f"servo{n}_raw")
        if MOTOR1 <= function < MOTOR1 + 8 and value != 1500 or function == 0 and value != 0:
            problems.append(f"SERVO{n} (function {function}) at {value} us while disarmed")
    return problems


def _intervals(kind: str, port: int) -> list[str]:
    """On a fuzzed link: GET_MESSAGE_INTERVAL answers for every message the vehicle sends, each interval off (-1)
    or between 1 ms and 60 s, as ArduPilot keeps them."""
    probe = IntervalProbe(kind, port)
    try:
        problems = []
        for msg_id, name in sorted(NAME_OF_ID.items()):
            interval_us, result = probe.ask(msg_id)
            if result != mav.MAV_RESULT_ACCEPTED or not (interval_us == -1 or 1000 <= interval_us <= 60_000_000):
                problems.append(f"{name} on {kind} link {port}: interval {interval_us} us, MAV_RESULT {result}")
        return problems
    finally:
        probe.sock.close()


class IntervalProbe:
    """GET_MESSAGE_INTERVAL on a link the traffic may have set to stream everything every millisecond: too much for
    pymavlink to parse, so frames are cut from the raw bytes and only the two answers decoded.

    Each request follows FLUSH zero bytes. Broken traffic can leave the vehicle's parser inside a bogus frame that
    swallows the start of the next; the request's payload ends in FE 01 (command 510), a MAVLink 1 start and length,
    so a byte-stream parser (pymavlink's, as the MAVLink C library's) can frame every identical resend the same wrong
    way and never see one. Zeros complete any pending frame and are never taken for a start byte."""

    def __init__(self, kind: str, port: int):
        self.sock = Sender._open(kind, port)
        self.encoder = mav.MAVLink(None, srcSystem=CHECKER_SYSID, srcComponent=190)
        self.decoder = mav.MAVLink(None)
        self.pending = bytearray()

    def ask(self, msg_id: int) -> tuple[int, int]:
        """(interval_us, MAV_RESULT), asking again every RETRY s until both answers came (AssertionError after WAIT)."""
        command = mav.MAV_CMD_GET_MESSAGE_INTERVAL
        request = self.encoder.command_long_encode(1, 1, command, 0, msg_id, 0, 0, 0, 0, 0, 0)
        interval = result = None
        deadline = time.monotonic() + WAIT
        while time.monotonic() < deadline:
            self.sock.send(bytes(FLUSH) + request.pack(self.encoder))
            self.encoder.seq = (self.encoder.seq + 1) % 256
            resend = time.monotonic() + RETRY
            while time.monotonic() < resend:
                for frame in self._frames():
                    m = self.decoder.decode(bytearray(frame))
                    if m.get_type() == "MESSAGE_INTERVAL" and m.message_id == msg_id & 0xFFFF:
                        interval = m.interval_us
                    elif m.get_type() == "COMMAND_ACK" and m.command == command and interval is not None:
                        result = m.result
                if result is not None:
                    return interval, result
        raise AssertionError(f"no answer to GET_MESSAGE_INTERVAL {msg_id} within {WAIT} s")

    def _frames(self) -> list[bytes]:
        """The MESSAGE_INTERVAL and COMMAND_ACK frames among what arrived (the vehicle's frames are well-formed)."""
        try:
            self.pending += self.sock.recv(1 << 16)
        except (BlockingIOError, InterruptedError):
            time.sleep(0.001)
            return []
        wanted, i, buf = [], 0, self.pending
        while i < len(buf):
            if buf[i] not in (STX_V1, STX_V2):
                i += 1
                continue
            v2 = buf[i] == STX_V2
            if i + 10 > len(buf):
                break
            size = (12 + buf[i + 1] + (SIGNATURE_LEN if buf[i + 2] & 1 else 0)) if v2 else 8 + buf[i + 1]
            if i + size > len(buf):
                break
            msg_id = buf[i + 7] | buf[i + 8] << 8 | buf[i + 9] << 16 if v2 else buf[i + 5]
            if msg_id in (mav.MAVLINK_MSG_ID_MESSAGE_INTERVAL, mav.MAVLINK_MSG_ID_COMMAND_ACK):
                wanted.append(bytes(buf[i:i + size]))
            i += size
        del self.pending[:i]
        return wanted


def requested(checker: Gcs, kind: str):
    """`kind` once, asked for with MAV_CMD_REQUEST_MESSAGE (whatever its stream rate was set to)."""
    msg_id = getattr(mav, f"MAVLINK_MSG_ID_{kind}")
    return checker.request(lambda: checker.send("command_long", 1, 1, mav.MAV_CMD_REQUEST_MESSAGE, 0, msg_id,
                                                0, 0, 0, 0, 0, 0), kind, lambda m: m.get_srcSystem() == 1)


def bridge_counters(output: str) -> tuple[int, int, int]:
    """(messages received, message types received, handler errors) from a stopped bridge's last lines."""
    found = COUNTERS.search(output)
    assert found, f"no message counts in the bridge's output:\n{output}"
    return int(found.group(1)), int(found.group(2)), int(found.group(3))
