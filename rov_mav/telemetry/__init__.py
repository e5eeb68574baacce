"""Live and recorded telemetry in the Rerun viewer.

- blueprint: the default layout
- entities: the entity tree, and the columnar logging of control ticks
- live: the runner's non-blocking sink
- recording: opening a recording and completing it
- target: where telemetry goes (--rerun; parsing only, no Rerun import)
- trace: a whole offline run logged in one go

The names below load their module (and with it the Rerun SDK) on first use, so that a command that only parses
`--rerun off` never imports Rerun."""

from __future__ import annotations

import importlib

_MODULE_OF = {
    "default_blueprint": "blueprint",
    "TIMELINE": "entities", "TickColumns": "entities", "send_convergence": "entities",
    "RerunSink": "live", "SinkStats": "live",
    "RerunTarget": "target", "default_target": "target", "parse_target": "target",
    "ViewerUnavailable": "recording", "finish": "recording", "open_recording": "recording",
    "log_trace": "trace", "mission_events": "trace", "trace_columns": "trace",
}

__all__ = sorted(_MODULE_OF)


def __getattr__(name: str):
    """A name above from its module, or a submodule itself (`telemetry.target`), imported on first use."""
    if name in set(_MODULE_OF.values()):
        return importlib.import_module(f"{__name__}.{name}")
    module = _MODULE_OF.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f"{__name__}.{module}"), name)
