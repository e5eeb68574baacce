"""Opening a `RerunTarget` as a Rerun recording stream, and completing it."""

from __future__ import annotations

import socket
import sys
from pathlib import Path
from urllib.parse import urlsplit

import rerun as rr
import rerun.blueprint as rrb

from rov_mav.telemetry.target import DEFAULT_URL, VIEWER_PORT, RerunTarget

APPLICATION_ID = "rov_mav"
FLUSH_TIMEOUT = 3.0   # s to hand the last data to a viewer before giving up on it


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
