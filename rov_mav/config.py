"""Loading YAML configuration files with one-line, located error messages."""

from __future__ import annotations

from pathlib import Path
from typing import Any, TypeVar

import yaml
from pydantic import BaseModel, ConfigDict, ValidationError

Model = TypeVar("Model", bound=BaseModel)


class ConfigError(ValueError):
    """A configuration file is unreadable or invalid; the message is one line: file, key, problem."""


class StrictModel(BaseModel):
    """Base for file schemas: unknown keys are errors, no silent type coercion from strings."""

    model_config = ConfigDict(extra="forbid", frozen=True, strict=True)


def read_yaml(path: str | Path) -> dict[str, Any]:
    """Read a YAML mapping from `path`; raise ConfigError naming the file on any problem."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read: {exc.strerror or exc}") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" (line {mark.line + 1})" if mark is not None else ""
        problem = getattr(exc, "problem", None) or "invalid YAML"
        raise ConfigError(f"{path}{where}: {problem}") from None
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: expected a mapping of keys at the top level")
    return data


def _location(loc: tuple[Any, ...]) -> str:
    parts: list[str] = []
    for item in loc:
        if isinstance(item, int):
            parts.append(f"[{item}]")
        elif item in ("function-after", "function-before", "function-plain") or str(item).startswith("function-"):
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
