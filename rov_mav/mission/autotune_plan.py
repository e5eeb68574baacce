"""What `rov-mav autotune` flies, inside a box around where the vehicle is: the shipped identification excitation
(missions/identify.yaml) moved so that it starts at the vehicle's position and the asked depth, and a short check leg
(a square with stop-and-turn corners) in the middle of the box, both with limits that keep the vehicle within
MAX_EXCURSION of the box: the run stops when it is that far from its reference, and every reference stays inside.
Pure: mission files' contents in, contents out; `outside` measures a loaded mission against the box.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np

from rov_mav.config import ConfigError
from rov_mav.mission.missions import Mission

MAX_EXCURSION = 0.5       # m: how far a run may stray from its reference (the box's limit) before it stops
SURFACE_CLEARANCE = 0.3   # m of water the excitation keeps above the vehicle at its shallowest
CHECK_SPEED = 0.2         # m/s along the check square's sides
CHECK_MARGIN = 0.5        # m between the check square and the box's sides
CHECK_TURN = 4.0          # s: each corner's hold while the vehicle turns to the next side
DRY_RUN_TRACKING = 100.0  # m: the dry run's tracking limit (a vehicle not flown drifts)
HOLD_CHECK = 5.0          # s: the dry run's hold at the excitation's start
SAMPLES = 0.1             # s between the reference samples a mission is measured at


@dataclass(frozen=True)
class Box:
    """An axis-aligned box in the local frame (north, east, down), m."""

    low: np.ndarray
    high: np.ndarray

    @property
    def size(self) -> np.ndarray:
        return self.high - self.low

    @property
    def centre(self) -> np.ndarray:
        return 0.5 * (self.low + self.high)

    def describe(self) -> str:
        (n0, e0, d0), (n1, e1, d1) = self.low, self.high
        return (f"{self.size[0]:g} x {self.size[1]:g} x {self.size[2]:g} m: north {n0:.2f}..{n1:.2f}, east "
                f"{e0:.2f}..{e1:.2f}, depth {d0:.2f}..{d1:.2f} m")


def extent(mission: Mission) -> tuple[np.ndarray, np.ndarray]:
    """The smallest box (low, high) holding the mission's reference position."""
    t = np.arange(0.0, mission.duration + SAMPLES, SAMPLES)
    position = mission.reference(t)[:, :3]
    return position.min(axis=0), position.max(axis=0)


def outside(mission: Mission, box: Box) -> float:
    """How far (m) the mission's reference goes outside the box at its worst (0 inside)."""
    low, high = extent(mission)
    return float(max(np.max(box.low - low), np.max(high - box.high), 0.0))


def moved_excitation(spec: dict, excitation: Mission, start: np.ndarray, size: np.ndarray) -> tuple[dict, Box]:
    """The excitation's mission file contents moved so that it starts at `start` (north, east, depth), and the box of
    `size` (m) around it, centred on the excitation's own extent; ConfigError (one line) when the excitation does not
    fit the box or would come within SURFACE_CLEARANCE of the surface."""
    low, high = extent(excitation)
    needed = high - low
    if np.any(needed > size + 1e-9):
        raise ConfigError(f"the excitation ({excitation.name}) needs {needed[0]:.1f} x {needed[1]:.1f} x "
                          f"{needed[2]:.1f} m; --box {size[0]:g},{size[1]:g},{size[2]:g} is smaller")
    shift = np.asarray(start, float) - excitation.start_pose[:3]
    if low[2] + shift[2] < SURFACE_CLEARANCE:
        rise = excitation.start_pose[2] - low[2]
        raise ConfigError(f"the excitation rises {rise:.1f} m above its start: start it at least "
                          f"{rise + SURFACE_CLEARANCE:.1f} m deep (--depth)")
    centre = 0.5 * (low + high) + shift
    box = Box(centre - size / 2, centre + size / 2)
    moved = copy.deepcopy(spec)
    moved["name"] = f"{spec['name']}_autotune"
    moved["start"]["position"] = _shifted(spec["start"]["position"], shift)
    for leg in moved["path"]:
        if "goto" in leg:
            leg["goto"] = _shifted(leg["goto"], shift)
    moved["limits"] = _limits(spec.get("limits", {}), box)
    return moved, box


def check_leg(box: Box) -> dict:
    """A square in the middle of the box at its middle depth, CHECK_MARGIN from its sides, flown at CHECK_SPEED
    facing along each side, with a hold at each corner to turn: the mission file's contents."""
    side = float(min(box.size[0], box.size[1]) - 2 * CHECK_MARGIN)
    if side < 1.0:
        raise ConfigError(f"the box ({box.describe()}) leaves no room for the check square (1 m a side at least)")
    n0, e0, depth = (float(v) for v in box.centre - np.array([side / 2, side / 2, 0.0]))
    corners = [(n0 + side, e0, 90), (n0 + side, e0 + side, 180), (n0, e0 + side, -90), (n0, e0, 0)]
    path = []
    for north, east, heading in corners:
        path.append({"goto": [round(north, 3), round(east, 3), round(depth, 3)], "speed": CHECK_SPEED})
        path.append({"hold": CHECK_TURN, "heading": f"{heading} deg"})
    return {"name": "autotune_check", "description": f"a {side:g} m square in the autotune box",
            "start": {"position": [round(n0, 3), round(e0, 3), round(depth, 3)], "heading": "0 deg"},
            "ramp_time": 2.0, "path": path, "limits": _limits({}, box)}


def hold_here(pose: np.ndarray, size: np.ndarray, limits: dict) -> dict:
    """A HOLD_CHECK s hold where the vehicle is (`pose`: north, east, depth m, heading rad), for the dry run that
    checks the vehicle before the plan is made. Nothing is flown in a dry run, so the vehicle keeps drifting where
    the water takes it: its tracking limit is DRY_RUN_TRACKING, its depth limit a box of `size` below it."""
    north, east, depth, heading = (float(v) for v in pose)
    return {"name": "autotune_vehicle_check", "description": "a hold where the vehicle is",
            "start": {"position": [round(north, 3), round(east, 3), round(depth, 3)],
                      "heading": f"{np.degrees(heading):.1f} deg"},
            "ramp_time": 1.0, "path": [{"hold": HOLD_CHECK}],
            "limits": {**limits, "max_depth": round(depth + float(size[2]) + MAX_EXCURSION, 3),
                       "max_tracking_error": DRY_RUN_TRACKING}}


def station_hold(square: dict, duration: float) -> dict:
    """A hold of `duration` s where the check square starts (the middle of the box's south-west part, at its middle
    depth): where the vehicle waits, flown, while the gains are tuned."""
    return {"name": "autotune_station", "description": "holding station while the gains are tuned",
            "start": copy.deepcopy(square["start"]), "ramp_time": 1.0, "path": [{"hold": round(duration, 1)}],
            "limits": dict(square["limits"])}


def _shifted(point, shift: np.ndarray) -> list[float]:
    return [round(float(v), 3) for v in np.asarray(point, float) + shift]


def _limits(own: dict, box: Box) -> dict:
    """The mission's limits with the box's: the depth at most MAX_EXCURSION below it, the run stopped MAX_EXCURSION
    from its reference."""
    return {**own, "max_depth": round(float(box.high[2]) + MAX_EXCURSION, 3), "max_tracking_error": MAX_EXCURSION}
