"""What an identified model is worth before it is written: its prediction one second ahead on a held-back part of
the logs, beside the prior's, and the physical sense of its parameters.

Prediction: from each logged state of the held-back part (every SPACING s), the model (the report's Eq. 2.7,
`dynamics.acceleration`) is integrated HORIZON s with the thrust the vehicle was sent (the bench curve at the sent
PWM and logged voltage, through the thruster geometry, `force_balance.bench_thrusts` and
`thrusters.allocation_matrix`), then compared with the state logged there: depth (m), heading, roll and pitch (deg).
The same for the prior: a fitted model that predicts worse than the prior it started from has learned the noise.

The held-back part is every third BLOCK s of each log (blocked cross-validation: a block is much longer than the
fit's windows and the horizon, so what is predicted was not fitted), not its last third: a flight's last third holds
only its last manoeuvres, and a fit of the rest keeps the prior for what those alone excite, a mixture that fits
neither vehicle (an autotune flight's first two thirds pinned surge but not sway down: the yaw moment of moving
diagonally, from the difference of the two added masses, changed sign, and the heading 1 s ahead came out 1.9 deg
RMS against the prior's 0.5 while the whole fit's was 0.05).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rov_mav.model.dynamics import acceleration, jacobian
from rov_mav.model.thrusters import allocation_matrix, thruster_curve
from rov_mav.model.vehicle import Vehicle
from rov_mav.offline.identify.force_balance import Run, bench_thrusts, rows
from rov_mav.units import wrap_angle

HORIZON = 1.0                 # s ahead
SPACING = 0.5                 # s between the starts of predictions
STEP = 0.01                   # s, integration step (RK4)
BLOCK = 10.0                  # s: each log is cut into blocks this long from its start ...
HELD_BACK = 1.0 / 3.0         # ... and every third one (the second of each three) is held back from the fit
QUANTITIES = (("depth_m", 2, 1.0), ("roll_deg", 3, np.degrees(1.0)), ("pitch_deg", 4, np.degrees(1.0)),
              ("heading_deg", 5, np.degrees(1.0)))   # (name, eta index, scale to the unit)
DECIDING = ("depth_m", "heading_deg")                 # a fit worse than the prior on these is not written
TIE = {"depth_m": 0.002, "heading_deg": 0.1, "roll_deg": 0.1, "pitch_deg": 0.1}   # differences below: a tie
TIE_SHARE = 0.01              # ... or below this share of the prior's error
NET_SHARE = 0.25              # |B - W| beyond this share of W: no trimmed ROV (a BlueROV2 floats by 1-3 % of W)


@dataclass(frozen=True)
class Comparison:
    """One quantity's RMS error HORIZON s ahead on the held-back data, for the fitted model and for the prior."""

    quantity: str
    fitted: float
    prior: float
    predictions: int

    @property
    def worse(self) -> bool:
        """The fit predicts worse than the prior beyond a tie (TIE, TIE_SHARE)."""
        return self.fitted - self.prior > max(TIE[self.quantity], TIE_SHARE * self.prior)


def split(run: Run, block: float = BLOCK) -> tuple[Run, Run]:
    """(the part to fit, the part to check): the run's BLOCK s blocks, the second of every three held back (so the
    first and the last are fitted, and a log as short as the fit's MIN_DURATION still has one to check)."""
    every = round(1.0 / HELD_BACK)
    held = np.floor((run.t - run.t[0]) / block).astype(int) % every == 1
    return rows(run, ~held), rows(run, held)


def ahead_errors(vehicle: Vehicle, run: Run, delay: float = 0.0, horizon: float = HORIZON,
                 spacing: float = SPACING) -> dict[str, np.ndarray]:
    """Per quantity, the error (predicted - logged) HORIZON s ahead from each start; all starts integrated at once."""
    t = run.t
    starts = _starts(t, horizon, spacing)
    if not starts.size:
        return {name: np.zeros(0) for name, _, _ in QUANTITIES}
    wrench = bench_thrusts(run, thruster_curve(vehicle)) @ allocation_matrix(vehicle.thruster_positions,
                                                                             vehicle.thruster_directions).T
    eta, nu = run.eta[starts].copy(), run.nu[starts].copy()
    t0 = t[starts]
    steps = int(round(horizon / STEP))
    for k in range(steps):
        now = t0 + k * STEP
        eta, nu = _rk4(vehicle, eta, nu, lambda s: _held(t, wrench, s - delay), now)
    logged = np.column_stack([np.interp(t0 + horizon, t, run.eta[:, i]) for i in range(6)])
    logged[:, 3:] = np.column_stack([_interp_angle(t0 + horizon, t, run.eta[:, i]) for i in range(3, 6)])
    out = {}
    for name, i, scale in QUANTITIES:
        error = eta[:, i] - logged[:, i]
        out[name] = scale * (wrap_angle(error) if i >= 3 else error)
    return out


def compare(fitted: Vehicle, prior: Vehicle, held: list[Run], delay: float) -> list[Comparison]:
    """Fitted against prior on the held-back runs, per quantity (RMS over every start of every run)."""
    ours = [ahead_errors(fitted, run, delay) for run in held]
    theirs = [ahead_errors(prior, run, delay) for run in held]
    out = []
    for name, _, _ in QUANTITIES:
        a = np.concatenate([e[name] for e in ours])
        b = np.concatenate([e[name] for e in theirs])
        if a.size:
            out.append(Comparison(name, _rms(a), _rms(b), int(a.size)))
    return out


def impossible(vehicle: Vehicle) -> str | None:
    """Why `vehicle` cannot be a real ROV (one line), or None: a mass matrix not positive definite, negative damping
    or added mass, or buoyancy and weight further apart than NET_SHARE of the weight."""
    if np.any(np.linalg.eigvalsh(0.5 * (vehicle.mass_matrix + vehicle.mass_matrix.T)) <= 0.0):
        return "its mass matrix (rigid body plus added mass) is not positive definite"
    for label, values in (("added mass", vehicle.added_mass), ("linear damping", vehicle.linear_damping),
                          ("quadratic damping", vehicle.quadratic_damping)):
        if np.any(values < 0.0):
            return f"its {label} is negative ({', '.join(f'{v:.3g}' for v in values)})"
    net = vehicle.buoyancy - vehicle.weight
    if abs(net) > NET_SHARE * vehicle.weight:
        return (f"its buoyancy {vehicle.buoyancy:.1f} N is {net:+.1f} N from its weight {vehicle.weight:.1f} N "
                f"(more than {NET_SHARE:.0%}): a trimmed ROV floats by a few newtons; it would "
                f"{'shoot up' if net > 0 else 'sink like a stone'}")
    return None


def _starts(t: np.ndarray, horizon: float, spacing: float) -> np.ndarray:
    """Indices of states at least `spacing` apart whose horizon stays within the run and within one unbroken
    stretch (no gap in the log longer than a quarter of the horizon)."""
    gaps = np.flatnonzero(np.diff(t) > 0.25 * horizon)
    out, last = [], -np.inf
    for i, ti in enumerate(t):
        if ti - last < spacing or ti + horizon > t[-1]:
            continue
        if np.any((t[gaps] >= ti) & (t[gaps] < ti + horizon)):
            continue
        out.append(i)
        last = ti
    return np.array(out, dtype=int)


def _held(t: np.ndarray, wrench: np.ndarray, at: np.ndarray) -> np.ndarray:
    """The wrench sent last before each time `at` (zero-order hold, as commands are held)."""
    index = np.clip(np.searchsorted(t, at, side="right") - 1, 0, t.size - 1)
    return wrench[index]


def _rk4(vehicle: Vehicle, eta: np.ndarray, nu: np.ndarray, tau_at, now: np.ndarray):
    def f(e, n, s):
        return np.einsum("kij,kj->ki", jacobian(e), n), acceleration(vehicle, e, n, tau_at(s))

    k1 = f(eta, nu, now)
    k2 = f(eta + 0.5 * STEP * k1[0], nu + 0.5 * STEP * k1[1], now + 0.5 * STEP)
    k3 = f(eta + 0.5 * STEP * k2[0], nu + 0.5 * STEP * k2[1], now + 0.5 * STEP)
    k4 = f(eta + STEP * k3[0], nu + STEP * k3[1], now + STEP)
    return (eta + STEP / 6.0 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0]),
            nu + STEP / 6.0 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1]))


def _interp_angle(at: np.ndarray, t: np.ndarray, angle: np.ndarray) -> np.ndarray:
    return np.interp(at, t, np.unwrap(angle))


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x ** 2)))
