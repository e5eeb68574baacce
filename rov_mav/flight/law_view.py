"""A navigation's errors as `rov-mav run`'s law meets them, for the offline loops: the vehicle's estimate through the
run's own shaping of it (`vehicle_state.StateDecoder` with a run's settings: a jump taken in at a flyable pace,
`estimate_jumps`; position and velocity blended, `estimate_blend`), so that `simulate`, `tune` and
`bench` fly on what a run on that navigation would fly on, not on an estimate no run acts on. Pure: no I/O.
"""

from __future__ import annotations

import numpy as np

from rov_mav.flight.estimate_jumps import EstimateJumps
from rov_mav.flight.run_options import RunOptions
from rov_mav.flight.estimate_blend import EstimateBlend
from rov_mav.model.dynamics import body_velocity, rotation


def as_the_run_sees(errors: np.ndarray, reference: np.ndarray, dt: float,
                    velocity_blend: float = RunOptions.velocity_blend) -> np.ndarray:
    """errors (N+1, 6): the estimate's position (NED) and body-velocity errors at t_k = k dt along `reference`
    (N+1, 18) -> the same errors after the run's shaping."""
    jumps, blend = EstimateJumps(), EstimateBlend(velocity_blend)
    shaped = np.empty_like(errors)
    body = body_velocity(reference[:, :6], reference[:, 6:12])[:, :3]
    for k in range(errors.shape[0]):
        eta = reference[k, :6]
        r = rotation(eta)
        nu = body[k]
        position = eta[:3] + errors[k, :3]
        v_ned = r @ (nu + errors[k, 3:])
        seen = jumps.steady(k * dt, position, v_ned)
        seen, v_seen = blend.update(k * dt, seen, v_ned + jumps.catch_up)
        shaped[k, :3] = seen - eta[:3]
        shaped[k, 3:] = r.T @ v_seen - nu
    return shaped

