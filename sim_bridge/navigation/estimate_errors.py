"""The built-in vehicle's navigation error along a path, for the offline loops: what `simulate`, `tune` and `bench`
add to the state the law sees when a mission's environment names a navigation (`environment: navigation`).

The same sensors (`sim_bridge.navigation.sensors`, seeded as the bridge seeds them) and the same estimator
(`sim_bridge.navigation.estimator`, the EKF3 stand-in) as the bridge, driven by the vehicle flying the mission's
reference
exactly (eta_d, and nu_d = J(eta_d)^-1 eta_dot_d); the estimate's error — its position less the true one, its body
velocity less the true one — sampled at every control tick. The offline loop's vehicle stays within centimetres of
the reference, and an acoustic fix's error depends on where the vehicle is only through its range from the
transceiver, so the error along the reference stands for the error along the flown path: the estimate lags, drifts
and steps as the bridge's does, without running the bridge's estimator inside the compiled loop.
"""

from __future__ import annotations

import numpy as np

from rov_mav.model.dynamics import body_velocity
from rov_mav.model.navigation import Navigation
from sim_bridge.navigation.estimator import Estimator
from sim_bridge.navigation.sensors import Sensors


def estimate_errors(navigation: Navigation, seed: int, reference: np.ndarray, dt: float) -> np.ndarray:
    """(N+1, 6): at each tick t_k = k dt of `reference` (N+1, 18), the estimate's position error (NED, m) and body
    velocity error (m/s). Zero for the ideal navigation."""
    n = reference.shape[0]
    errors = np.zeros((n, 6))
    if navigation.ideal:
        return errors
    eta = reference[:, :6]
    nu = body_velocity(eta, reference[:, 6:12])
    sensors = Sensors(navigation, seed, eta[0], nu[0])
    estimator = Estimator(navigation, 0.0, eta[0], nu[0])
    for k in range(n):
        t = k * dt
        if t + 1e-9 >= sensors.next_event:
            for item in sensors.sample(t, eta[k], nu[k]):
                estimator.feed(item)
        estimate_eta, estimate_nu = estimator.output
        errors[k, :3] = estimate_eta[:3] - eta[k, :3]
        errors[k, 3:] = estimate_nu[:3] - nu[k, :3]
    return errors

