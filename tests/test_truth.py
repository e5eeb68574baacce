"""The true position a simulator puts on the link (`flight.session.truth`), and the metrics against it."""

from __future__ import annotations

import math

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from rov_mav.flight.session.truth import Truth
from rov_mav.mission.metrics import truth_metrics
from rov_mav.units import EARTH_RADIUS

ENCODER = mavlink.MAVLink(None)
ORIGIN = (-35.363261, 149.165230, 0.0)


def _sim_state(north: float, east: float, down: float, ints: bool = True):
    lat = ORIGIN[0] + math.degrees(north / EARTH_RADIUS)
    lon = ORIGIN[1] + math.degrees(east / (EARTH_RADIUS * math.cos(math.radians(ORIGIN[0]))))
    msg = ENCODER.sim_state_encode(1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, lat, lon, ORIGIN[2] - down, 0, 0, 0, 0, 0,
                                   round(lat * 1e7) if ints else 0, round(lon * 1e7) if ints else 0)
    return _decoded(msg)


def _origin():
    return _decoded(ENCODER.gps_global_origin_encode(round(ORIGIN[0] * 1e7), round(ORIGIN[1] * 1e7),
                                                      round(ORIGIN[2] * 1e3), 0))


def _decoded(msg):
    """The message as a receiver gets it (packed and parsed: fields as the wire carries them)."""
    return mavlink.MAVLink(None).decode(bytearray(msg.pack(mavlink.MAVLink(None))))


def test_sim_state_becomes_the_ned_position_the_vehicle_reports_its_estimate_in():
    truth = Truth()
    assert not truth.update(_sim_state(3.0, -4.0, 2.5), 1.0)          # no origin yet: no truth
    truth.update(_origin(), 1.1)
    assert truth.update(_sim_state(3.0, -4.0, 2.5), 1.2)
    assert np.allclose(truth.position, [3.0, -4.0, 2.5], atol=0.02) and truth.t == 1.2   # 1e-7 deg is about 1 cm
    truth.update(_sim_state(10.0, 10.0, 1.0, ints=False), 1.3)        # float degrees only: coarser
    assert np.allclose(truth.position[:2], [10.0, 10.0], atol=1.0)


def test_truth_metrics_only_where_the_truth_is_known():
    eta_d = np.zeros((4, 6))
    truth = np.array([[0.0, 0.0, 0.0], [0.3, 0.4, 0.0], [np.nan] * 3, [0.0, 0.0, 0.1]])
    m = truth_metrics(truth, eta_d)
    assert m["truth_samples"] == 3 and np.isclose(m["max_position_error_truth_m"], 0.5)
    assert np.isclose(m["rms_position_error_truth_m"], math.sqrt((0.25 + 0.01) / 3))
    assert truth_metrics(np.full((4, 3), np.nan), eta_d) == {}
