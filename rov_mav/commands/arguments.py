"""Command-line values checked where they enter: argparse types for numbers in range, MAVLink ids, connection
strings, shipped file names and output paths.

A bad value is refused by argparse before anything runs, in one line naming the option (exit status 2, see
`rov_mav.cli`). Output paths given by default (out/...) are checked with `require_writable` the same way.
Nothing here creates or opens anything.
"""

from __future__ import annotations

import argparse
import math
import os
import re
import stat
from collections.abc import Callable
from pathlib import Path

from rov_mav import shipped
from rov_mav.config import ConfigError
from sim_bridge.transport.link import TransportError, parse_endpoint

MAVLINK_KINDS = ("udp", "udpin", "udpout", "udpbcast", "tcp", "tcpin")   # pymavlink's network connections
MAX_SPEEDUP = 1000.0       # beyond it a 400 Hz step would get 2.5 us of wall time: the vehicle could only slip
MAX_WAIT = 3600.0          # s: the longest timeout worth waiting for
MAX_SEED = 2**32 - 1       # what numpy's and the noise generators' seeds take


def number(low: float, high: float = math.inf, *, integer: bool = False, low_open: bool = False
           ) -> Callable[[str], float]:
    """An argparse type: a finite number (an integer if `integer`) with low <= x <= high (low < x if
    `low_open`); NaN and infinity are refused."""
    kind = "an integer" if integer else "a number"
    bound = f"above {_show(low)}" if low_open else f"at least {_show(low)}"
    wanted = (f"{kind} from {_show(low)} to {_show(high)}" if not low_open and math.isfinite(high)
              else f"{kind} {bound}" + (f" and at most {_show(high)}" if math.isfinite(high) else ""))

    def parse(text: str) -> float:
        try:
            value = int(text, 10) if integer else float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text}: not {kind}") from None
        if not (math.isfinite(value) and (value > low if low_open else value >= low) and value <= high):
            raise argparse.ArgumentTypeError(f"{text}: expected {wanted}")
        return value
    return parse


def _show(value: float) -> str:
    """A bound as a user would write it: 4294967295, 0.0001, 14400."""
    return str(int(value)) if float(value).is_integer() else f"{value:g}"


positive_float = number(0.0, low_open=True)
seconds = number(0.0, MAX_WAIT, low_open=True)
speedup = number(0.0, MAX_SPEEDUP, low_open=True)
sysid = number(1, 255, integer=True)            # MAVLink system ids; 0 is the broadcast address
seed = number(0, MAX_SEED, integer=True)


def count(high: int) -> Callable[[str], int]:
    """An argparse type: an integer from 1 to `high`."""
    return number(1, high, integer=True)


def finite_floats(size: int) -> Callable[[str], list[float]]:
    """An argparse type: `size` comma-separated finite numbers."""
    def parse(text: str) -> list[float]:
        try:
            values = [float(v) for v in text.split(",")]
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text}: not {size} comma-separated numbers") from None
        if len(values) != size:
            raise argparse.ArgumentTypeError(f"{text}: {len(values)} values, expected {size}")
        if not all(math.isfinite(v) for v in values):
            raise argparse.ArgumentTypeError(f"{text}: NaN or infinity")
        return values
    return parse


six_floats = finite_floats(6)
plan_speed = number(0.0, 1.5, low_open=True)     # m/s: a BlueROV2 Heavy's top speed (mission_items.MAX_SPEED)


def lat_lon(text: str) -> tuple[float, float]:
    """An argparse type: 'LAT,LON' in degrees, on Earth."""
    lat, lon = finite_floats(2)(text)
    if not (abs(lat) <= 90 and abs(lon) <= 180):
        raise argparse.ArgumentTypeError(f"{text}: latitude within +-90, longitude within +-180 degrees")
    return lat, lon


# -- input files --------------------------------------------------------------------------------------------------

def shipped_file(kind: str) -> Callable[[str], str]:
    """An argparse type: a path as given, or the name of a shipped file of `kind` (`rov_mav.shipped.resolve`)."""
    def parse(text: str) -> str:
        try:
            return shipped.resolve(kind, text)
        except ConfigError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None
    return parse


mission_file = shipped_file("mission")
scenarios_file = shipped_file("scenario set")
vehicle_file = shipped_file("vehicle")


# -- connection strings -------------------------------------------------------------------------------------------

def endpoint(kinds: tuple[str, ...]) -> Callable[[str], str]:
    """An argparse type: KIND:HOST:PORT with KIND one of `kinds` (see `sim_bridge.transport.link.parse_endpoint`)."""
    def parse(text: str) -> str:
        if not text.strip():
            raise argparse.ArgumentTypeError("empty connection string")
        try:
            parse_endpoint(text, kinds)
        except TransportError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None
        return text
    return parse


def mavlink_target(text: str) -> str:
    """An argparse type: a pymavlink connection string, checked before anything connects: udp/udpin/udpout/
    udpbcast/tcp/tcpin:HOST:PORT, or the path of a serial (character) device that exists."""
    if not text.strip():
        raise argparse.ArgumentTypeError("empty connection string")
    kind, colon, _ = text.partition(":")
    if kind in MAVLINK_KINDS:
        return endpoint(MAVLINK_KINDS)(text)
    if colon and not text.startswith(("/", ".")):
        raise argparse.ArgumentTypeError(f"{text}: expected {', '.join(MAVLINK_KINDS)}:HOST:PORT or a serial "
                                         "device such as /dev/ttyACM0")
    try:
        mode = os.stat(text).st_mode
    except OSError as exc:
        raise argparse.ArgumentTypeError(f"{text}: no such serial device ({(exc.strerror or '').lower()})") from None
    if not stat.S_ISCHR(mode):
        raise argparse.ArgumentTypeError(f"{text}: not a serial device")
    return text


CLUSTER_LOCAL = re.compile(r"local:(\d+)")
MAX_WORKERS = 256


def cluster_address(text: str) -> str:
    """An argparse type: 'local:N' (1 <= N <= MAX_WORKERS worker processes) or 'tcp://HOST:PORT' (a Dask scheduler)."""
    local = CLUSTER_LOCAL.fullmatch(text)
    if local is not None:
        if len(local.group(1)) <= 3 and 1 <= int(local.group(1)) <= MAX_WORKERS:
            return text
        raise argparse.ArgumentTypeError(f"{text}: local:N needs a number of workers N from 1 to {MAX_WORKERS}")
    if text.startswith("tcp://"):
        try:
            parse_endpoint("tcp:" + text.removeprefix("tcp://"), ("tcp",))
        except TransportError:
            raise argparse.ArgumentTypeError(f"{text}: expected tcp://HOST:PORT, PORT from 1 to 65535") from None
        return text
    raise argparse.ArgumentTypeError(f"{text}: neither local:N nor tcp://HOST:PORT")


# -- output paths -------------------------------------------------------------------------------------------------

def unwritable(path: str | Path, folder: bool) -> str | None:
    """Why a file (or a folder, if `folder`) could not be written at `path`, or None if it could: checked on the
    path and its nearest existing ancestor, creating nothing."""
    if not str(path).strip():
        return "empty path"
    path = Path(path)
    try:
        if path.exists():
            if path.is_dir() != folder:
                return "exists and is not a folder" if folder else "is a folder, expected a file name"
            return None if os.access(path, os.W_OK | (os.X_OK if folder else 0)) else "permission denied"
        ancestor = path.parent
        while not ancestor.exists():
            ancestor = ancestor.parent
    except OSError as exc:
        return (exc.strerror or str(exc)).lower()
    if not ancestor.is_dir():
        return f"{ancestor} is not a folder"
    if not os.access(ancestor, os.W_OK | os.X_OK):
        return f"cannot create anything in {ancestor}: permission denied"
    return None


def require_writable(path: str | Path, *, folder: bool, option: str) -> Path:
    """`path`, or ConfigError '{option} {path}: reason' when it cannot be written (see `unwritable`)."""
    problem = unwritable(path, folder)
    if problem is not None:
        raise ConfigError(f"{option} {path}: {problem}")
    return Path(path)


def _output(folder: bool) -> Callable[[str], str]:
    def parse(text: str) -> str:
        problem = unwritable(text, folder)
        if problem is not None:
            raise argparse.ArgumentTypeError(f"{text}: {problem}" if text else problem)
        return text
    return parse


output_file = _output(folder=False)
output_folder = _output(folder=True)
