"""What the navigation sources' BlueOS extensions put on the link, as their drivers fill it (they post through
mavlink2rest, and the router forwards to every endpoint: the autopilot and every ground station see them).

- Water Linked UGPS extension (waterlinked/blueos-ugps-extension `app/main.py`, `app/mavlink2resthelper.py`
  `send_gps_input`): GPS_INPUT from system 1, component 220 (hard-coded there, whatever the vehicle's sysid), at
  every poll whether or not there is a fix: ignore_flags ALT|VEL_HORIZ|VEL_VERT|SPEED_ACCURACY|VERT_ACCURACY,
  fix_type 3 with a fix (horiz_accuracy and vdop the acoustic standard deviation, hdop the topside GPS's), else 0
  with horiz_accuracy 300 and hdop/vdop 65535; lat/lon floored to 1e-7 deg; yaw the vehicle's heading in cdeg with 0
  sent as 36000. time_usec, time_week and time_week_ms stay 0 (the helper's template).
- Water Linked DVL extension (bluerobotics/BlueOS-Water-Linked-DVL `dvl-a50/dvl.py` `handle_velocity`,
  `mavlink2resthelper.py` `send_vision`): VISION_POSITION_DELTA from system 255, component 0 (the template's header),
  one per valid velocity report: position_delta = velocity x the report's interval (body frame, DVL facing down),
  time_delta_usec that interval, angle_delta 0 (the driver no longer feeds attitude back), time_usec 0, confidence
  100 x (1 - min(fom, 0.4) / 0.4).
"""

from __future__ import annotations

import math

from sim_bridge.navigation.sensors import DvlReport, UgpsFix
from sim_bridge.gcs.telemetry import EARTH_RADIUS, ENCODER

UGPS_SOURCE = (1, 220)                 # (sysid, compid) of the UGPS extension's GPS_INPUT
DVL_SOURCE = (255, 0)                  # of the DVL extension's VISION_POSITION_DELTA
GPS_INPUT_IGNORE = 1 | 8 | 16 | 32 | 128
TOPSIDE_HDOP, TOPSIDE_SATELLITES = 0.9, 10    # the topside's own GPS (chosen)
FOM_MAX = 0.4                          # m/s: the driver's "inaccurate" figure of merit


def gps_input(fix: UgpsFix, origin: tuple[float, float, float], heading: float):
    lat0, lon0, _ = origin
    lat = lat0 + math.degrees(fix.north / EARTH_RADIUS)
    lon = lon0 + math.degrees(fix.east / (EARTH_RADIUS * math.cos(math.radians(lat0))))
    if fix.valid:
        fix_type, horiz, hdop, vdop = 3, fix.std, TOPSIDE_HDOP, fix.std
    else:
        fix_type, horiz, hdop, vdop = 0, 300.0, 65535.0, 65535.0
    yaw = math.floor(math.degrees(heading) % 360.0 * 100) or 36000
    return ENCODER.gps_input_encode(0, 0, GPS_INPUT_IGNORE, 0, 0, fix_type, math.floor(lat * 1e7),
                                    math.floor(lon * 1e7), 0.0, hdop, vdop, 0.0, 0.0, 0.0, 0.0, horiz, 0.0,
                                    TOPSIDE_SATELLITES, yaw)


def vision_position_delta(report: DvlReport):
    delta = [float(v * report.dt) for v in report.velocity]
    confidence = 100.0 * (1.0 - min(FOM_MAX, report.fom) / FOM_MAX)
    return ENCODER.vision_position_delta_encode(0, int(report.dt * 1e6), [0.0, 0.0, 0.0], delta, confidence)


def source_messages(items: list, origin: tuple[float, float, float], heading: float) -> list:
    """(message, (sysid, compid)) for each fix and DVL report that has reached the companion computer."""
    out = []
    for item in items:
        if isinstance(item, UgpsFix):
            out.append((gps_input(item, origin, heading), UGPS_SOURCE))
        elif isinstance(item, DvlReport):
            out.append((vision_position_delta(item), DVL_SOURCE))
    return out
