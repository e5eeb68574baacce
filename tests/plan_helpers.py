"""Test support: QGroundControl `.plan` files written the way QGC writes them (every key its SimpleItem and
survey save, null for NaN), and the same items in the QGC WPL 110 text format MAVProxy's `wp load` reads."""

from __future__ import annotations

import json
import math
from pathlib import Path

HOME = (47.3977419, 8.545594, 488.0)       # QGC's documentation example home: lat, lon, AMSL alt
EARTH_MEAN_RADIUS = 6371008.8              # m (IUGG mean radius), the sphere of the haversine formula
NAV_WAYPOINT, NAV_TAKEOFF, DO_CHANGE_SPEED, DO_SET_CAM_TRIGG_DIST = 16, 22, 178, 206


def simple_item(seq: int, command: int, params: list, frame: int = 3) -> dict:
    """A SimpleItem as QGC's SimpleMissionItem::save writes it (frame 3 = altitude relative to home)."""
    altitude = params[6] if params[6] is not None else 0
    return {"AMSLAltAboveTerrain": None, "Altitude": altitude, "AltitudeMode": 1 if frame == 3 else 2,
            "autoContinue": True, "command": command, "doJumpId": seq, "frame": frame, "params": params,
            "type": "SimpleItem"}


def waypoint(seq: int, lat: float, lon: float, alt: float, hold: float = 0, yaw: float | None = None,
             frame: int = 3) -> dict:
    return simple_item(seq, NAV_WAYPOINT, [hold, 0, 0, yaw, lat, lon, alt], frame)


def survey(first_seq: int, transects: list[tuple[tuple[float, float], tuple[float, float]]], depth: float,
           trigger_distance: float = 0.0) -> dict:
    """A survey ComplexItem holding the items QGC generates (TransectStyleComplexItem::_buildAndAppendMissionItems,
    no turnarounds): each transect's entry and exit waypoints, and with a camera trigger distance a
    DO_SET_CAM_TRIGG_DIST after each (start at entry, stop at exit)."""
    items, seq = [], first_seq
    for entry, exit_ in transects:
        for point, distance in ((entry, trigger_distance), (exit_, 0.0)):
            items.append({"autoContinue": True, "command": NAV_WAYPOINT, "doJumpId": seq, "frame": 3,
                          "params": [0, 0, 0, None, point[0], point[1], -depth], "type": "SimpleItem"})
            seq += 1
            if trigger_distance:
                items.append({"autoContinue": True, "command": DO_SET_CAM_TRIGG_DIST, "doJumpId": seq, "frame": 2,
                              "params": [distance, 0, 1, 0, 0, 0, 0], "type": "SimpleItem"})
                seq += 1
    points = [list(p) for t in transects for p in t]
    lats, lons = [p[0] for p in points], [p[1] for p in points]
    polygon = [[min(lats), min(lons)], [min(lats), max(lons)], [max(lats), max(lons)], [max(lats), min(lons)]]
    return {"TransectStyleComplexItem": {
                "CameraCalc": {"AdjustedFootprintFrontal": trigger_distance, "AdjustedFootprintSide": 4,
                               "CameraName": "Manual (no camera specs)", "DistanceMode": 1,
                               "DistanceToSurface": -depth, "version": 2},
                "CameraShots": 0, "CameraTriggerInTurnAround": True, "HoverAndCapture": False, "Items": items,
                "Refly90Degrees": False, "TurnAroundDistance": 0, "VisualTransectPoints": points, "version": 2},
            "angle": 0, "complexItemType": "survey", "entryLocation": 0, "flyAlternateTransects": False,
            "polygon": polygon, "splitConcavePolygons": False, "type": "ComplexItem", "version": 5}


def plan(items: list[dict], home: tuple[float, float, float] = HOME, cruise_speed: float = 0.3) -> dict:
    """A whole plan file as QGC saves it for an ArduSub vehicle."""
    return {"fileType": "Plan", "geoFence": {"circles": [], "polygons": [], "version": 2},
            "groundStation": "QGroundControl",
            "mission": {"cruiseSpeed": cruise_speed, "firmwareType": 3, "globalPlanAltitudeMode": 1,
                        "hoverSpeed": cruise_speed, "items": items, "plannedHomePosition": list(home),
                        "vehicleType": 12, "version": 2},
            "rallyPoints": {"points": [], "version": 2}, "version": 1}


def write_plan(path: Path, items: list[dict], **kwargs) -> Path:
    path.write_text(json.dumps(plan(items, **kwargs), indent=4))
    return path


def wpl(items: list[dict], home: tuple[float, float, float] = HOME) -> str:
    """The plan's simple items as QGC WPL 110 (item 0 = home, absolute altitude; NaN written as 0, as MAVLink has
    no null)."""
    lines = ["QGC WPL 110", f"0\t1\t0\t16\t0\t0\t0\t0\t{home[0]:.8f}\t{home[1]:.8f}\t{home[2]:.6f}\t1"]
    for seq, item in enumerate(items, start=1):
        p = [0.0 if v is None else v for v in item["params"]]
        lines.append("\t".join([str(seq), "0", str(item["frame"]), str(item["command"]),
                                *(f"{v:.8f}" for v in p), "1"]))
    return "\n".join(lines) + "\n"


def haversine(a: tuple[float, float], b: tuple[float, float]) -> float:
    """Great-circle distance in m between two (lat, lon) in degrees on the mean sphere."""
    phi1, phi2 = math.radians(a[0]), math.radians(b[0])
    dphi, dlam = phi2 - phi1, math.radians(b[1] - a[1])
    h = math.sin(dphi / 2) ** 2 + math.cos(phi1) * math.cos(phi2) * math.sin(dlam / 2) ** 2
    return 2 * EARTH_MEAN_RADIUS * math.asin(math.sqrt(h))
