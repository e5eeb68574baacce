"""Live and recorded telemetry in the Rerun viewer: entities (`entities`), default layout (`blueprint`), where it
goes (`target`), the runner's non-blocking sink (`live`) and whole offline runs (`trace`)."""

from rov_mav.telemetry.blueprint import default_blueprint
from rov_mav.telemetry.entities import TIMELINE, TickColumns, send_convergence
from rov_mav.telemetry.live import RerunSink, SinkStats
from rov_mav.telemetry.target import (
                                     RerunTarget,
                                     ViewerUnavailable,
                                     default_target,
                                     finish,
                                     open_recording,
                                     parse_target,
)
from rov_mav.telemetry.trace import log_trace, mission_events, trace_columns

__all__ = ["TIMELINE", "RerunSink", "RerunTarget", "SinkStats", "TickColumns", "ViewerUnavailable", "default_blueprint",
           "default_target", "finish", "log_trace", "mission_events", "open_recording", "parse_target",
           "send_convergence", "trace_columns"]
