"""Where a run's telemetry goes: `--rerun spawn | connect[:URL] | save:FILE.rrd | off` (parsing only: no Rerun import,
so that reading a command line costs nothing; `recording` opens it)."""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import urlsplit

VIEWER_PORT = 9876    # Rerun's default, where `spawn` starts (or finds) a viewer
DEFAULT_URL = f"rerun+http://127.0.0.1:{VIEWER_PORT}/proxy"
MODES = ("spawn", "connect", "save", "off")
URL_SCHEMES = ("rerun", "rerun+http", "rerun+https")


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
    """ValueError unless `url` is a viewer URL with a host (and a valid port, if any):
    rerun+http(s)://HOST[:PORT]/..."""
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
