"""Excitation signals for system identification: a multisine or a chirp offset added to a hold's pose on one DOF.

The offset along the DOF is x(t) = w(t) sum_k a_k sin(phi_k + 2 pi f_k t + pi c_k t^2), with w a taper that rises
from 0 to 1 over the first tenth of the segment and falls back over the last (smootherstep, 6u^5 - 15u^4 + 10u^3,
whose first and second derivatives vanish at both ends), so the reference's pose, velocity and acceleration stay
continuous across the segment's boundaries. Position, velocity and acceleration are analytic.

- multisine: components log-spaced over the band, amplitudes a_k ~ 1/f_k (the same velocity amplitude for each,
  so low frequencies, which show damping, and high ones, which show added mass, are excited alike), Schroeder
  phases (a low crest factor); scaled so that the peak offset equals the amplitude asked for.
- chirp: one component whose frequency sweeps linearly over the band, at the amplitude asked for.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

AXES = ("surge", "sway", "heave", "roll", "pitch", "yaw")
SIGNALS = ("multisine", "chirp")
MULTISINE_COMPONENTS = 8
TAPER_FRACTION = 0.1        # of the segment's duration, at each end
PEAK_GRID = 4000            # samples over the segment to find the multisine's peak


@dataclass(frozen=True)
class Excitation:
    """An offset x(t) along `direction` (6,) in eta space over [0, duration]; components (K,) each."""

    direction: np.ndarray      # (6,) unit vector in eta = [x, y, z, phi, theta, psi]
    duration: float            # s
    amplitudes: np.ndarray     # (K,) m or rad
    frequencies: np.ndarray    # (K,) Hz at t = 0
    sweep_rates: np.ndarray    # (K,) Hz/s (chirp), 0 for a fixed frequency
    phases: np.ndarray         # (K,) rad

    def offset(self, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(pose, velocity, acceleration) offsets (n, 6) at times tau (n,) s since the segment's start."""
        tau = np.clip(np.asarray(tau, dtype=float), 0.0, self.duration)
        x, dx, ddx = _window(tau, self.duration)
        s, ds, dds = self._signal(tau)
        pos = x * s
        vel = dx * s + x * ds
        acc = ddx * s + 2.0 * dx * ds + x * dds
        d = self.direction
        return pos[:, None] * d, vel[:, None] * d, acc[:, None] * d

    def _signal(self, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        t = tau[:, None]
        phase = self.phases + 2.0 * np.pi * (self.frequencies * t + 0.5 * self.sweep_rates * t**2)
        rate = 2.0 * np.pi * (self.frequencies + self.sweep_rates * t)
        sin, cos = np.sin(phase), np.cos(phase)
        a = self.amplitudes
        return ((a * sin).sum(1), (a * cos * rate).sum(1),
                (a * (cos * 2.0 * np.pi * self.sweep_rates - sin * rate**2)).sum(1))


def _window(tau: np.ndarray, duration: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The taper w and its first two derivatives: smootherstep up over the first TAPER_FRACTION, down over the last."""
    ramp = TAPER_FRACTION * duration
    u = np.clip(np.minimum(tau, duration - tau) / ramp, 0.0, 1.0)
    sign = np.where(tau <= 0.5 * duration, 1.0, -1.0)      # d/dtau of the distance to the nearer end
    inside = (u > 0.0) & (u < 1.0)
    w = u**3 * (10.0 - 15.0 * u + 6.0 * u**2)
    dw = np.where(inside, 30.0 * u**2 * (1.0 - u) ** 2 / ramp, 0.0) * sign
    ddw = np.where(inside, 60.0 * u * (1.0 - u) * (1.0 - 2.0 * u) / ramp**2, 0.0)
    return w, dw, ddw


def axis_direction(axis: str, heading: float) -> np.ndarray:
    """Unit vector (6,) in eta space for a body axis at `heading` rad: surge and sway turn with the heading."""
    d = np.zeros(6)
    c, s = np.cos(heading), np.sin(heading)
    if axis == "surge":
        d[:2] = (c, s)
    elif axis == "sway":
        d[:2] = (-s, c)
    else:
        d[AXES.index(axis)] = 1.0
    return d


def excitation(axis: str, signal: str, amplitude: float, band: tuple[float, float], duration: float,
               heading: float) -> Excitation:
    """A multisine or chirp of peak `amplitude` (m, or rad for roll/pitch/yaw) on `axis` over `band` Hz."""
    direction = axis_direction(axis, heading)
    low, high = band
    if signal == "chirp":
        return Excitation(direction, duration, np.array([amplitude]), np.array([low]),
                          np.array([(high - low) / duration]), np.zeros(1))
    k = np.arange(1, MULTISINE_COMPONENTS + 1)
    freqs = np.geomspace(low, high, MULTISINE_COMPONENTS)
    phases = -np.pi * k * (k - 1) / MULTISINE_COMPONENTS
    unit = Excitation(direction, duration, 1.0 / freqs, freqs, np.zeros_like(freqs), phases)
    peak = np.abs(unit._signal(np.linspace(0.0, duration, PEAK_GRID))[0]).max()
    return Excitation(direction, duration, amplitude / (freqs * peak), freqs, np.zeros_like(freqs), phases)
