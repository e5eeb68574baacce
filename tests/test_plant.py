"""The stateful plant the bridge steps is the same model the offline simulation integrates."""

from __future__ import annotations

import numpy as np

from rov_mav.model import kernel
from rov_mav.model.environment import Environment
from rov_mav.model.plant import Plant


def test_plant_steps_match_the_kernel(vehicle):
    env = Environment(disturbance=np.array([-1.0, 1.0, 2.0, 0.1, 0.1, 0.0]), current=np.array([0.1, 0.0, 0.0]))
    eta0 = np.array([1.0, 2.0, 3.0, 0.1, -0.1, 0.5])
    plant = Plant(vehicle, env, eta0=eta0)
    x = np.concatenate([eta0, np.zeros(6)])
    ws = np.zeros(80)
    tau = np.array([10.0, -5.0, 3.0, 0.2, 0.1, -0.3])
    for k in range(200):
        plant.step(tau, 0.005)
        kernel.rk4_step(vehicle.packed(), env.packed(), x, tau, k * 0.005, 0.005, ws)
    np.testing.assert_array_equal(np.concatenate([plant.eta, plant.nu]), x)
    assert abs(plant.t - 1.0) < 1e-12


def test_measured_noise_has_the_configured_spread(vehicle):
    env = Environment(noise=np.array([0.02, 0.01, 0.05, 0.003]))
    plant = Plant(vehicle, env, seed=1)
    samples = np.array([np.concatenate(plant.measured()) for _ in range(4000)])
    expected = np.repeat([0.02, 0.01, 0.05, 0.003], 3)
    np.testing.assert_allclose(samples.std(axis=0), expected, rtol=0.08)
    assert (np.abs(samples.mean(axis=0)) < 4 * expected / np.sqrt(4000)).all()
