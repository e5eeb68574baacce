"""The navigation errors the offline loops fly on are the run's law's view of them (`flight.state.estimate_shaping`):
nothing added where the estimate is exact, a jump of the estimate taken in at the run's pace, not at once, and the
same shaped state as the run's own decoder makes of the same samples."""

from __future__ import annotations

import numpy as np

from rov_mav.flight.state.estimate_jumps import CATCH_UP
from rov_mav.flight.state.estimate_shaping import VELOCITY_BLEND, as_the_run_sees
from rov_mav.flight.state.vehicle_state import StateDecoder
from rov_mav.model.dynamics import body_velocity, rotation
from rov_mav.mission.missions import mission_from_dict

DT = 0.01


def _reference():
    mission = mission_from_dict({"name": "leg", "start": {"position": [0.0, 0.0, 1.0], "heading": 0.0},
                                 "path": [{"goto": [6.0, 0.0, 1.0], "speed": 0.3}]}, "leg.yaml")
    return mission.sampled_reference(DT, None)


def test_an_exact_estimate_stays_exact():
    """The position within 2 mm, the velocity within 1 mm/s (the blend integrates the velocity by steps)."""
    ref = _reference()
    seen = as_the_run_sees(np.zeros((ref.shape[0], 6)), ref, DT)
    np.testing.assert_allclose(seen[:, :3], 0.0, atol=2e-3)
    np.testing.assert_allclose(seen[:, 3:], 0.0, atol=1e-3)


def test_a_jump_of_the_estimate_reaches_the_law_at_the_runs_pace():
    ref = _reference()
    errors = np.zeros((ref.shape[0], 6))
    jump_at = int(5.0 / DT)
    errors[jump_at:, 1] = 1.0                    # the estimate moves 1 m east and stays there
    seen = as_the_run_sees(errors, ref, DT)
    pace = np.abs(np.diff(seen[:, 1])) / DT
    assert pace.max() <= 1.1 * CATCH_UP           # the run's pace (the blend after it overshoots it by 5 %)
    assert seen[jump_at + int(1.0 / DT), 1] < 0.1   # a second later, most of it still held back
    assert abs(seen[-1, 1] - 1.0) < 0.05          # and in the end the law sees where the estimate is


class _Message:
    def __init__(self, kind: str, **fields):
        self._kind = kind
        self.__dict__.update(fields)

    def get_type(self) -> str:
        return self._kind


def test_the_offline_loops_and_the_run_shape_the_same_samples_alike():
    """The reference flown with a wandering estimate and a 1 m jump, sent as ArduSub's ATTITUDE and
    LOCAL_POSITION_NED at 50 Hz to the run's decoder (`StateDecoder` as `run_io` makes it): its states are the
    offline loops' `as_the_run_sees` of the same errors, to float precision."""
    dt = 0.02
    ref = _reference()[::2]
    n = ref.shape[0]
    k = np.arange(n)
    errors = np.column_stack([0.05 * np.sin(0.3 * k * dt), 0.02 * np.cos(0.2 * k * dt), np.zeros(n),
                              0.01 * np.sin(0.5 * k * dt), np.zeros(n), 0.005 * np.ones(n)])
    errors[n // 2:, 1] += 1.0
    offline = as_the_run_sees(errors, ref, dt)
    decoder = StateDecoder(VELOCITY_BLEND, steady=True)
    body = body_velocity(ref[:, :6], ref[:, 6:12])
    run = np.empty_like(errors)
    for i in range(n):
        eta = ref[i, :6]
        position, v_ned = eta[:3] + errors[i, :3], rotation(eta) @ (body[i, :3] + errors[i, 3:])
        stamp = int(round(i * dt * 1000))
        decoder.update(_Message("ATTITUDE", time_boot_ms=stamp, roll=eta[3], pitch=eta[4], yaw=eta[5],
                                rollspeed=0.0, pitchspeed=0.0, yawspeed=0.0))
        assert decoder.update(_Message("LOCAL_POSITION_NED", time_boot_ms=stamp, x=position[0], y=position[1],
                                       z=position[2], vx=v_ned[0], vy=v_ned[1], vz=v_ned[2]))
        state = decoder.state(0.0)
        run[i, :3] = state.eta[:3] - eta[:3]
        run[i, 3:] = state.nu[:3] - body[i, :3]
    np.testing.assert_allclose(run, offline, atol=1e-9)
