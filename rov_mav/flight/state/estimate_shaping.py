"""The run's shaping of the vehicle's estimate before its law sees it, written once for the run
(`vehicle_state.StateDecoder`) and the offline loops (`as_the_run_sees`): a jump of the reported position taken in
at a pace the vehicle can fly (`estimate_jumps`; a run's, not a review's), then position and velocity blended below
`velocity_blend` rad/s (`estimate_blend`). `simulate`, `tune` and `bench` thus fly on what a run on that
navigation would fly on, not on an estimate no run acts on. Pure: no I/O.
"""

from __future__ import annotations

import numpy as np

from rov_mav.flight.state.estimate_blend import EstimateBlend
from rov_mav.flight.state.estimate_jumps import EstimateJumps
from rov_mav.model.dynamics import body_velocity, rotation

VELOCITY_BLEND = 0.2      # rad/s: a run's default blend (`run --velocity-blend`)


class EstimateShaping:
    """`shape(t, position, v_ned)` -> the law's (position, NED velocity), each (3,); one call per state sample."""

    def __init__(self, velocity_blend: float = VELOCITY_BLEND, steady: bool = True):
        self.jumps = EstimateJumps() if steady else None
        self.blend = EstimateBlend(velocity_blend)

    def shape(self, t: float, position: np.ndarray, v_ned: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if self.jumps is not None:
            position = self.jumps.steady(t, position, v_ned)
            v_ned = v_ned + self.jumps.catch_up
        return self.blend.update(t, position, v_ned)


def as_the_run_sees(errors: np.ndarray, reference: np.ndarray, dt: float,
                    velocity_blend: float = VELOCITY_BLEND) -> np.ndarray:
    """errors (N+1, 6): the estimate's position (NED) and body-velocity errors at t_k = k dt along `reference`
    (N+1, 18) -> the same errors after a run's shaping (`EstimateShaping`)."""
    shaping = EstimateShaping(velocity_blend)
    shaped = np.empty_like(errors)
    body = body_velocity(reference[:, :6], reference[:, 6:12])[:, :3]
    for k in range(errors.shape[0]):
        eta = reference[k, :6]
        r = rotation(eta)
        seen, v_seen = shaping.shape(k * dt, eta[:3] + errors[k, :3], r @ (body[k] + errors[k, 3:]))
        shaped[k, :3] = seen - eta[:3]
        shaped[k, 3:] = r.T @ v_seen - body[k]
    return shaped
