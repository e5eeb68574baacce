"""Where a run's telemetry goes: `--rerun spawn | connect[:URL] | save:FILE.rrd | off`, and opening it."""

from __future__ import annotations

import os
import socket
import sys
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import urlsplit

import rerun as rr
import rerun.blueprint as rrb

APPLICATION_ID = "rov_mav"
VIEWER_PORT = 9876    # Rerun's default, where `spawn` starts (or finds) a viewer
DEFAULT_URL = f"rerun+http://127.0.0.1:{VIEWER_PORT}/proxy"
MODES = ("spawn", "connect", "save", "off")
URL_SCHEMES = ("rerun", "rerun+http", "rerun+https")
FLUSH_TIMEOUT = 3.0   # s to hand the last data to a viewer before giving up on it


@dataclass(frozen=True)
class RerunTarget:
    """mode: spawn | connect | save | off; location: the viewer URL (connect) or the .rrd path (save)."""

    mode: str
    location: str | None = None

    def describe(self, delivered: bool = True) -> str:
        """One line for the user: where the telemetry went (`delivered`: as `finish` returned)."""
        if not delivered:
            return f"the viewer ({self.mode}) did not take all the data in time"
        if self.mode == "save":
            return f"recording {self.location} (open it with: rerun {self.location})"
        if self.mode == "connect":
            return f"streamed to the viewer at {self.location}"
        return "streamed to a spawned viewer" if self.mode == "spawn" else "off"


def parse_target(text: str) -> RerunTarget:
    """'spawn', 'connect', 'connect:URL', 'save:FILE.rrd' or 'off'; ValueError otherwise."""
    mode, _, location = text.partition(":")
    if mode not in MODES:
        raise ValueError(f"'{text}': expected spawn, connect[:URL], save:FILE.rrd or off")
    if mode == "save" and not location:
        raise ValueError("save needs a file: save:FILE.rrd")
    if mode in ("spawn", "off") and location:
        raise ValueError(f"'{mode}' takes no argument")
    if mode == "connect" and location:
        _check_url(location)
    return RerunTarget(mode, location or (DEFAULT_URL if mode == "connect" else None))


def _check_url(url: str) -> None:
    """ValueError unless `url` is a viewer URL with a host (and a valid port, if any): rerun+http(s)://HOST[:PORT]/..."""
    parts = urlsplit(url)
    try:
        parts.port
    except ValueError:
        raise ValueError(f"'{url}': the port must be a number from 0 to 65535") from None
    if parts.scheme not in URL_SCHEMES or not parts.hostname:
        raise ValueError(f"'{url}': expected a viewer URL like {DEFAULT_URL}")


def default_target(default_file: str | Path, environ: Mapping[str, str] = os.environ) -> RerunTarget:
    """Spawn a viewer when there is a display, else save to `default_file`."""
    if environ.get("DISPLAY") or environ.get("WAYLAND_DISPLAY"):
        return RerunTarget("spawn")
    return RerunTarget("save", str(default_file))


class ViewerUnavailable(ConnectionError):
    """No viewer listens where the telemetry should go."""


def _require_listening(url: str, timeout: float = 2.0) -> None:
    """Raise ViewerUnavailable unless something accepts TCP connections at the URL's host and port."""
    parts = urlsplit(url)
    host, port = parts.hostname or "127.0.0.1", parts.port or VIEWER_PORT
    try:
        socket.create_connection((host, port), timeout=timeout).close()
    except OSError as exc:
        raise ViewerUnavailable(f"no Rerun viewer at {url} ({exc.strerror or exc})") from None


def _viewer_executable() -> str | None:
    """The `rerun` next to this interpreter (a virtualenv not on PATH), else None: Rerun then searches PATH."""
    candidate = Path(sys.executable).with_name("rerun")
    return str(candidate) if candidate.exists() else None


def open_recording(target: RerunTarget, blueprint: rrb.Blueprint) -> rr.RecordingStream | None:
    """A recording stream to the target with `blueprint` as its default layout; None when off.

    ViewerUnavailable when no viewer listens at a connect URL, or a spawned viewer did not start (no display)."""
    if target.mode == "off":
        return None
    rec = rr.RecordingStream(APPLICATION_ID)
    if target.mode == "save":
        Path(target.location).parent.mkdir(parents=True, exist_ok=True)
        rec.save(target.location, default_blueprint=blueprint)
        return rec
    url = target.location if target.mode == "connect" else DEFAULT_URL
    if target.mode == "spawn":   # starts a viewer unless one already listens on VIEWER_PORT
        rr.spawn(port=VIEWER_PORT, connect=False, recording=rec, executable_path=_viewer_executable())
    _require_listening(url)
    rec.connect_grpc(url, default_blueprint=blueprint)
    return rec


def finish(rec: rr.RecordingStream, timeout: float = FLUSH_TIMEOUT) -> bool:
    """Hand over what is buffered (a file is completed) and disconnect; False if a viewer did not take it in time."""
    try:
        rec.flush(timeout_sec=timeout)
        delivered = True
    except RuntimeError:
        delivered = False
    rec.disconnect()
    return delivered
