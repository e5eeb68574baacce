"""`run --estimator model`: the navigation sources' messages and the vehicle's state turned into the model-aided
filter's measurements (`model_estimator`), and the state the law flies on made of its estimate.

The sources speak on the link through the vehicle's companion computer, from their own system ids
(`sim_bridge.navigation.source_messages` cites the BlueOS drivers): GPS_INPUT from the acoustic positioning system (a
fix when
fix_type >= 3; its horiz_accuracy the standard deviation; latitude and longitude from the EKF origin,
GPS_GLOBAL_ORIGIN), VISION_POSITION_DELTA from the DVL (position_delta over time_delta_usec: the body velocity).
Neither carries a usable time of validity (their drivers leave time_usec 0), so each is stamped with the vehicle
time it arrives at. Pure: no I/O.
"""

from __future__ import annotations

import numpy as np

from rov_mav.flight.state.model_estimator import ModelEstimator
from rov_mav.units import north_east
from rov_mav.flight.state.vehicle_state import State

FIX_TYPE_3D = 3


class OwnNavigation:
    """`source(msg, t, origin)` for every message on the link; `state(state)` -> the state the law flies on: the
    vehicle's until a navigation source has given a measurement (then the filter starts from it: the law sees no
    jump), the filter's output after (the vehicle's own position kept as `reported`)."""

    def __init__(self, model_packed: np.ndarray):
        self.filter = ModelEstimator(model_packed)
        self.started_by: str | None = None        # what started the filter ("an acoustic fix", "a DVL report")
        self._last: State | None = None           # the latest state the vehicle gave

    def source(self, msg, t: float, origin: tuple[float, float, float] | None) -> None:
        """A message heard at vehicle time t; the EKF origin, once known, places the acoustic fixes."""
        kind = msg.get_type()
        fix = kind == "GPS_INPUT" and msg.fix_type >= FIX_TYPE_3D and origin is not None
        dvl = kind == "VISION_POSITION_DELTA" and msg.time_delta_usec > 0
        if (fix or dvl) and not self.filter.started and self._last is not None:
            self.filter.start(self._last.t, self._last.eta, self._last.nu)
            self.started_by = "an acoustic fix (GPS_INPUT)" if fix else "a DVL report (VISION_POSITION_DELTA)"
        if not self.filter.started:
            return
        if fix:
            north, east = north_east(msg.lat * 1e-7, msg.lon * 1e-7, origin)
            self.filter.fix(t, north, east, float(msg.horiz_accuracy))
        elif dvl:
            self.filter.dvl(t, np.array(msg.position_delta, dtype=float) / (msg.time_delta_usec * 1e-6))
        elif kind == "GPS_INPUT":
            self.filter.heard(t)       # a source on the link in a dropout: it speaks, and is not replaced

    def commanded(self, t_act: float, wrench: np.ndarray) -> None:
        self.filter.commanded(t_act, wrench)

    def figures(self) -> dict:
        """What the filter did with each kind of measurement (fused, gated out, valid before the steps it keeps or
        after its time) and how often it reset its position to a fix: the `own_estimator` block of the metrics."""
        f = self.filter
        return {"started_by": self.started_by, "fused": dict(f.fused), "refused": dict(f.refused),
                "too_old": dict(f.too_old), "ahead": dict(f.ahead), "resets": f.resets}

    def state(self, state: State) -> State:
        """The state at state.t the law flies on (see the class)."""
        self._last = state
        f = self.filter
        if not f.started:
            return state
        reported = state.reported if state.reported is not None else state.eta[:3]
        f.advance(state.t, np.concatenate([state.eta[3:6], state.nu[3:6]]))
        f.depth(state.t, float(reported[2]))
        f.vehicle(state.t, float(reported[0]), float(reported[1]), state.nu[:3])
        eta, nu = state.eta.copy(), state.nu.copy()
        eta[:3], nu[:3] = f.position, f.velocity
        return State(state.t, eta, nu, state.received, reported=reported.copy())
