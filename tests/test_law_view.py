"""The navigation errors the offline loops fly on are the run's law's view of them (`flight.law_view`): nothing added
where the estimate is exact, and a jump of the estimate taken in at the run's pace, not at once."""

from __future__ import annotations

import numpy as np

from rov_mav.flight.estimate_jumps import CATCH_UP
from rov_mav.flight.law_view import as_the_run_sees
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
