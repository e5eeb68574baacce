"""The true simulated vehicle as a stateful object, stepped by whoever owns the clock (the bridge).

It is a thin shell over the compiled model (`rov_mav.model.kernel.rk4_step`), the same one `simulate` integrates.
"""

from __future__ import annotations

import numpy as np

from rov_mav.model import kernel
from rov_mav.model.environment import Environment
from rov_mav.model.vehicle import Vehicle


class Plant:
    """6-DOF state (eta, nu) of a vehicle in an environment, advanced by RK4 steps with a held wrench."""

    def __init__(self, vehicle: Vehicle, environment: Environment | None = None, eta0: np.ndarray | None = None,
                 nu0: np.ndarray | None = None, seed: int = 0):
        self.vehicle = vehicle
        self.environment = environment if environment is not None else Environment()
        self._params = vehicle.packed()
        self._env = self.environment.packed()
        self._x = np.zeros(12)
        if eta0 is not None:
            self._x[:6] = eta0
        if nu0 is not None:
            self._x[6:] = nu0
        self._ws = np.zeros(80)
        self._rng = np.random.default_rng(seed)
        self.t = 0.0

    @property
    def eta(self) -> np.ndarray:
        """True pose [x, y, z, phi, theta, psi] (NED, ZYX Euler), a copy."""
        return self._x[:6].copy()

    @property
    def nu(self) -> np.ndarray:
        """True body velocity [u, v, w, p, q, r] (FRD), a copy."""
        return self._x[6:].copy()

    def step(self, tau: np.ndarray, h: float) -> None:
        """Advance by h seconds with the control wrench tau (6,) held; the environment's disturbance is added."""
        kernel.rk4_step(self._params, self._env, self._x, np.asarray(tau, dtype=float), self.t, h, self._ws)
        self.t += h

    def measured(self) -> tuple[np.ndarray, np.ndarray]:
        """(eta, nu) as a sensor suite reports them: the true state plus the environment's Gaussian noise."""
        position, attitude, velocity, rate = self.environment.noise
        sigma = np.array([position] * 3 + [attitude] * 3 + [velocity] * 3 + [rate] * 3)
        noisy = self._x + self._rng.normal(size=12) * sigma
        return noisy[:6], noisy[6:]
