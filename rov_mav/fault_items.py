"""The grammar the two fault options share: comma-separated items `KEY[=VALUE][@TIME]`, given inline or in a YAML file.

The bridge's link faults (`sim_bridge.transport.faults`, 'loss=0.2,cut=30s@20s') and the vehicle's own faults
(`rov_mav.model.vehicle_faults`, 'thruster=3:dead@60s,reboot@90s') read their items here, so an item, an `@TIME`, a
time with its unit and a file read alike in both; each grammar checks its own keys and values and words its own
errors (`error` builds the exception a caller raises). Pure: no I/O beyond reading the file.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from rov_mav.config import ConfigError, read_yaml
from rov_mav.units import parse_duration

Error = Callable[[str], Exception]


@dataclass(frozen=True)
class Item:
    """One item: `text` as given (stripped), `key` in lower case, `value` after '=' (or the '@TIME' of a `KEY@TIME`
    item), `assigned` whether it had an '='."""

    text: str
    key: str
    value: str
    assigned: bool


def split_items(text: str) -> list[str]:
    """'a=1, b@2s' -> ['a=1', 'b@2s']: the comma-separated items, empty ones left out."""
    return [part.strip() for part in text.split(",") if part.strip()]


def parse_item(text: str) -> Item:
    """An item's key and value: 'KEY=VALUE' (the value may hold '@TIME') or 'KEY@TIME' (the value is '@TIME')."""
    text = text.strip()
    key, sep, value = text.partition("=")
    if not sep:
        key, at, when = text.partition("@")
        value = "@" + when if at else ""
    return Item(text, key.strip().lower(), value, bool(sep))


def at_time(body: str) -> tuple[str, str | None]:
    """'WHAT@TIME' -> (WHAT, TIME); (body, None) without an '@' (the last one splits)."""
    head, sep, when = body.rpartition("@")
    return (head, when) if sep else (body, None)


def seconds(text: str, error: Error, message: str) -> float:
    """A time of 0 or more with its unit ('50ms', '2s', '1min') in seconds; error(message) if it is not one."""
    value = parse_duration(text)
    if value is None:
        raise error(message)
    return value


def option_file(arg: str, error: Error, inline_form: str) -> tuple[dict, Path]:
    """The YAML file an option names that is not given inline: (its mapping, its path); error('<file>: why') in one
    line if it cannot be read, adding ' (nor INLINE_FORM)' when no such file exists."""
    path = Path(arg)
    try:
        return read_yaml(path), path
    except ConfigError as exc:
        hint = "" if path.exists() else f" (nor {inline_form})"
        raise error(f"{exc}{hint}") from None
