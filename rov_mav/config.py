"""Loading YAML configuration files with one-line, located error messages.

Any file given as configuration is read the same guarded way (`read_text`): a regular file of at most
MAX_FILE_BYTES of UTF-8 text, opened without blocking (a FIFO or a device is refused, not waited on), never read
beyond the limit. YAML is then measured from its event stream before any tree is built: deeper than
MAX_YAML_DEPTH, more than MAX_YAML_NODES values with aliases expanded (a "billion laughs"), or an alias inside
its own anchor is refused; only then is it loaded with a safe loader.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path
from typing import Any, TypeVar

import yaml
from pydantic import BaseModel, ConfigDict, ValidationError

Model = TypeVar("Model", bound=BaseModel)

MAX_FILE_BYTES = 1 << 20        # 1 MiB: the shipped files are a few kB; a mission of 10,000 segments is ~0.5 MiB
MAX_YAML_NODES = 100_000        # values in the document with every alias expanded
MAX_YAML_DEPTH = 50             # nested collections (a mission needs 4)
_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)   # libyaml: a 1 MiB file in well under 1 s, Python ~20 s


class ConfigError(ValueError):
    """A configuration file is unreadable or invalid; the message is one line: file, key, problem."""


class StrictModel(BaseModel):
    """Base for file schemas: unknown keys are errors, no silent type coercion from strings."""

    model_config = ConfigDict(extra="forbid", frozen=True, strict=True, allow_inf_nan=False)


def read_bytes(path: str | Path, limit: int = MAX_FILE_BYTES) -> bytes:
    """The content of the regular file `path`, at most `limit` bytes; ConfigError naming it otherwise."""
    if not str(path).strip():
        raise ConfigError("empty file name")
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    except FileNotFoundError:
        raise ConfigError(f"{path}: no such file") from None
    except OSError as exc:
        raise ConfigError(f"{path}: cannot open: {(exc.strerror or str(exc)).lower()}") from None
    info = os.fstat(fd)
    problem = ("is a directory, expected a file" if stat.S_ISDIR(info.st_mode)
               else "not a regular file (a device, FIFO or socket)" if not stat.S_ISREG(info.st_mode)
               else f"too large ({info.st_size:,} bytes; at most {limit:,})" if info.st_size > limit else None)
    if problem is not None:
        os.close(fd)
        raise ConfigError(f"{path}: {problem}")
    with os.fdopen(fd, "rb") as f:
        try:
            data = f.read(limit + 1)
        except OSError as exc:
            raise ConfigError(f"{path}: cannot read: {(exc.strerror or str(exc)).lower()}") from None
    if len(data) > limit:
        raise ConfigError(f"{path}: too large (more than {limit:,} bytes)")
    return data


def read_text(path: str | Path, kind: str = "YAML") -> str:
    """The UTF-8 text of a small regular file (`read_bytes`); ConfigError if it is binary or not UTF-8."""
    data = read_bytes(path)
    if b"\0" in data:
        raise ConfigError(f"{path}: not a text {kind} file (binary)")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{path}: not a text {kind} file (byte 0x{data[exc.start]:02x} at offset {exc.start} "
                          "is not UTF-8)") from None


def _check_shape(text: str, source: str | Path) -> None:
    """Walk the YAML events once (no tree built): ConfigError if collections nest deeper than MAX_YAML_DEPTH or
    the document, every alias expanded, holds more than MAX_YAML_NODES values, or an alias refers to its own
    container. After this the composer (libyaml recurses in C) and the schemas only ever see a small tree."""
    total = 0
    open_collections: list[tuple[str | None, int]] = []   # (anchor, values counted before it)
    anchored: dict[str, int] = {}                         # anchor -> expanded size of its value
    for event in yaml.parse(text, Loader=_LOADER):
        if isinstance(event, yaml.CollectionStartEvent):
            open_collections.append((event.anchor, total))
            total += 1
            if len(open_collections) > MAX_YAML_DEPTH:
                raise ConfigError(f"{source}: nested more than {MAX_YAML_DEPTH} levels deep")
        elif isinstance(event, yaml.CollectionEndEvent):
            anchor, before = open_collections.pop()
            if anchor is not None:
                anchored[anchor] = total - before
        elif isinstance(event, yaml.ScalarEvent):
            total += 1
            if event.anchor is not None:
                anchored[event.anchor] = 1
        elif isinstance(event, yaml.AliasEvent):
            if any(anchor == event.anchor for anchor, _ in open_collections):
                raise ConfigError(f"{source}: alias *{event.anchor} refers to the value that contains it")
            total += anchored.get(event.anchor, 1)   # an undefined one is the composer's to report
        if total > MAX_YAML_NODES:
            raise ConfigError(f"{source}: more than {MAX_YAML_NODES:,} values once aliases are expanded")


def parse_yaml(text: str, source: str | Path) -> Any:
    """Safe YAML of bounded expanded size; ConfigError naming `source` (and the line) otherwise."""
    try:
        _check_shape(text, source)
        return yaml.load(text, Loader=_LOADER)   # noqa: S506 -- a safe loader (CSafeLoader or SafeLoader)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" (line {mark.line + 1})" if mark is not None else ""
        problem = getattr(exc, "problem", None) or "invalid YAML"
        raise ConfigError(f"{source}{where}: {problem}") from None
    except ValueError as exc:   # an integer of more than 4300 digits
        if isinstance(exc, ConfigError):
            raise
        raise ConfigError(f"{source}: {str(exc).split(';')[0]}") from None


def read_yaml(path: str | Path) -> dict[str, Any]:
    """Read a YAML mapping from `path`; raise ConfigError naming the file on any problem."""
    data = parse_yaml(read_text(path), path)
    if data is None:
        raise ConfigError(f"{path}: empty (no keys)")
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: expected a mapping of keys at the top level")
    return data


def _location(loc: tuple[Any, ...]) -> str:
    parts: list[str] = []
    for item in loc:
        if isinstance(item, int):
            parts.append(f"[{item}]")
        elif str(item).startswith(("function-", "constrained-")):
            continue
        else:
            parts.append(("." if parts else "") + str(item))
    return "".join(parts) or "(top level)"


def parse(model: type[Model], data: dict[str, Any], path: str | Path) -> Model:
    """Validate `data` against `model`; raise ConfigError with the first problem as 'file: key: reason'."""
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        err = exc.errors()[0]
        reason = err["msg"]
        if err["type"] == "extra_forbidden":
            reason = "unknown key"
        elif err["type"] == "missing":
            reason = "missing"
        reason = reason.removeprefix("Value error, ")
        raise ConfigError(f"{path}: {_location(tuple(err['loc']))}: {reason}") from None


def load(model: type[Model], path: str | Path) -> Model:
    """Read and validate a YAML file in one step."""
    return parse(model, read_yaml(path), path)
