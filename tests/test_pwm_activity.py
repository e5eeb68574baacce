"""The thrusters' activity a run reports (`mission.metrics.pwm_activity`): sum |dPWM| per second, per thruster."""

from __future__ import annotations

import numpy as np

from rov_mav.mission.metrics import pwm_activity


def test_a_dithering_thruster_counts_every_step_and_steady_ones_nothing():
    t = np.arange(0.0, 10.0 + 1e-9, 0.02)
    pwm = np.full((t.size, 8), 1500.0)
    pwm[:, 0] += np.where(np.arange(t.size) % 2, 10.0, -10.0)     # 20 us every 20 ms
    assert np.isclose(pwm_activity(t, pwm), 20.0 * (t.size - 1) / 10.0 / 8)


def test_a_ramp_counts_its_travel_once_and_unknown_outputs_are_skipped():
    t = np.linspace(0.0, 4.0, 201)
    pwm = np.tile(np.linspace(1500.0, 1700.0, t.size)[:, None], (1, 8))
    pwm[50:60] = np.nan                                            # no output known (a GUIDED run before a report)
    assert np.isclose(pwm_activity(t, pwm), 200.0 / 4.0)
    assert np.isnan(pwm_activity(t[:1], pwm[:1]))
