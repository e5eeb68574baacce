"""System identification: the vehicle model fitted to flown runs (`rov-mav identify`). Pure numpy/scipy.

The model is the report's Eq. 2.7 without disturbance (Fossen 2021, Handbook of Marine Craft Hydrodynamics and
Motion Control, Ch. 6-7: rigid body, added mass, m2c Coriolis, damping, restoring forces of a submerged vehicle):

    M nu_dot + C(nu) nu + D(nu) nu + g(eta) = tau
    M = M_RB + diag(A)                         (Eq. 2.8; M_RB from the prior's mass and inertia, which are known)
    C(nu) from M by m2c                        (ERRATA 5): linear in M, so each A_i has its own Coriolis column
    D(nu) = diag(D_l) + diag(D_q) |nu|         (Appendix I.3, Eq. 2.10)
    g(eta): force -(W - B) rho, moment -((W - B) r_g - B lambda) x rho, rho = R^T e_z, lambda = r_b - r_g
                                               (Appendix I.4; W = m g known, B and lambda unknown)
    tau = B(sigma) (k_fwd F+ + k_rev F-)       (thrusters.allocation_matrix; F = the T200 data's thrust at the sent
                                                PWM and the logged voltage, split by sign, lagged by the thrusters'
                                                time constant and delayed by the link)

B(sigma) is the allocation matrix with three moment arms scaled: the vertical thrusters' lateral arm (roll), their
longitudinal arm (pitch), the horizontal thrusters' planar arms (yaw); each scale touches only its own moment row.

Equation error in integral form: over consecutive windows [t_a, t_b] of each run,

    M (nu_b - nu_a) + int (C nu + D nu + g) dt = int tau dt,

so no velocity is differentiated (sensor noise is averaged, not amplified) and the held, lagged commands integrate
exactly (int f = int u - T_f (f(t_b) - f(t_a)) for a first-order lag of time constant T_f). The windows' residuals,
divided by the window length (mean N or N m) and weighted per DOF by their RMS, are minimised jointly over the six
DOFs (they share A through C, k_fwd and k_rev through tau, lambda_z through roll and pitch) by nonlinear least squares;
the link's delay is chosen on a grid by the same fit. 95 % confidence intervals come from the Jacobian at the
optimum, widened for the residuals' correlation from one window to the next.

What the data cannot tell apart, and what is done about it:
- the level: scaling M, D, W - B, B lambda and the thrust by one factor leaves every equation unchanged when M_RB is
  diagonal (r_g = 0) -- motion shows forces only relative to the thrust. One number must come from elsewhere: the
  forward thrust scale stays the prior's (the thrusters' bench data), or a measured net buoyancy (the vehicle's
  weight in water) fixes B and frees the thrust scale.
- then, greedily, one parameter at a time: a direction the fit cannot see at all (a near-null singular vector of the
  column-scaled Jacobian) fixes its most likely culprit at the prior (moment arms before the rest: they are measured
  with a ruler); a parameter whose 95 % interval is wider than RELATIVE_PRECISION of its size (and than a floor
  scaled by the rigid body) stays at the prior. Each says why.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.signal import savgol_filter

from rov_mav.model.dynamics import coriolis, jacobian, rotation
from rov_mav.model.kernel import compiled
from rov_mav.model.thrusters import NEUTRAL_PWM, T200, allocation_matrix, thruster_curve
from rov_mav.model.vehicle import Vehicle
from rov_mav.offline.tuning import feedforward

DOFS = ("surge", "sway", "heave", "roll", "pitch", "yaw")
WINDOW = 0.4                  # s, length of the integration windows
SMOOTHING = 0.5               # s, span of the Savitzky-Golay filter applied to every term
SMOOTHING_ORDER = 2
MIN_DURATION = 30.0           # s of flight in all runs together
GAP_FACTOR = 3.0              # a tick further than this many median periods from the last starts a new piece
DELAY_STEPS = 5               # delays tried: 0, 1/2, ..., 2 control periods
VOLTAGE_RESOLUTION = 0.01     # V: the bench thrust is looked up at the logged voltage rounded to this
STILL_THRUST = 0.1            # N: logs whose thrusters never pushed harder than this have nothing to fit
RELATIVE_PRECISION = 0.1      # a fitted value is kept when its 95 % CI half-width is within 10 % of its size
ARM_PRECISION = 0.01          # ... 1 % for a moment arm, which a ruler measures about that well
FLOOR_FRACTION = 0.02         # ... or below this fraction of the rigid body's mass (inertia) in the DOF's units
STRUCTURAL = 1e-6             # singular value ratio of the column-scaled Jacobian below which a direction is blind
NOT_EXCITED = 1e-6            # a parameter whose forces are this small beside the largest one's is not excited
VIF_MAX = 1.0e4               # variance inflation beyond which a parameter is too collinear with others to fit
Z95 = 1.959964
MAX_ITERATIONS = 50
ARM_ORDER = ("arm_roll", "arm_pitch", "arm_yaw")
# Lower bounds of the parameter vector: added mass, damping, buoyancy and scales are not negative (the vehicle
# file's rules); the lever is free.
LOWER = np.concatenate([np.zeros(19), np.full(3, -np.inf), np.zeros(5)])


class IdentificationError(ValueError):
    """The runs cannot give a model (too short, not excited); the message is one line."""


@dataclass(frozen=True)
class Run:
    """A flown run at its control ticks: what identification needs of a run log (SI units, NED/FRD)."""

    name: str
    t: np.ndarray         # (N,) s of vehicle time, increasing
    eta: np.ndarray       # (N, 6) measured pose
    nu: np.ndarray        # (N, 6) measured body velocity
    pwm: np.ndarray       # (N, 8) us as sent (mirrored for thrusters whose MOT_n_DIRECTION is -1)
    thrusts: np.ndarray   # (N, 8) N, what the controller allocated (its sign tells a mirrored PWM)
    voltage: np.ndarray   # (N,) V the controller mapped thrust to PWM at
    reference: np.ndarray  # (N, 18) eta_d, eta_dot_d, eta_ddot_d the controller was tracking
    age: np.ndarray       # (N,) s of vehicle time from the state to the command leaving (0 for an ideal loop)


@dataclass(frozen=True)
class Estimate:
    """One parameter: fitted (half_width > 0 is its 95 % CI), or kept at the prior / given (status says why)."""

    name: str
    unit: str
    value: float
    prior: float
    half_width: float     # nan when not fitted
    status: str           # "fitted", "given: ...", or "prior: <why>"


@dataclass(frozen=True)
class DofFit:
    """How well the identified model explains one DOF's force (or moment) balance over the windows."""

    dof: str
    r2: float
    rms: float            # N or N m, mean over a window
    unit: str


@dataclass(frozen=True)
class Identification:
    vehicle: Vehicle                 # the prior with every fitted value in
    estimates: tuple[Estimate, ...]
    fits: tuple[DofFit, ...]
    delay: float                     # s, command-to-thrust delay found
    windows: int
    duration: float                  # s of flight used


@dataclass(frozen=True)
class _Parameter:
    name: str
    unit: str
    floor: float                        # a 95 % half-width below this is precise enough, whatever the value
    precision: float = RELATIVE_PRECISION   # ... or below this fraction of the value (or of the prior)


def _parameters(prior: Vehicle) -> list[_Parameter]:
    rigid = np.diag(prior.rigid_body_mass_matrix)
    units = [("kg", "N s/m", "N s^2/m^2")] * 3 + [("kg m^2", "N m s/rad", "N m s^2/rad^2")] * 3
    out = [_Parameter(f"added_mass.{d}", units[i][0], FLOOR_FRACTION * rigid[i]) for i, d in enumerate(DOFS)]
    out += [_Parameter(f"linear_damping.{d}", units[i][1], FLOOR_FRACTION * rigid[i]) for i, d in enumerate(DOFS)]
    out += [_Parameter(f"quadratic_damping.{d}", units[i][2], FLOOR_FRACTION * rigid[i]) for i, d in enumerate(DOFS)]
    out += [_Parameter("buoyancy", "N", 1e-3 * prior.weight)]
    out += [_Parameter(f"lever.{a}", "m", 5e-4) for a in "xyz"]
    out += [_Parameter("thrust_scale.forward", "", 0.01), _Parameter("thrust_scale.reverse", "", 0.01)]
    out += [_Parameter(name, "", 0.0, ARM_PRECISION) for name in ARM_ORDER]
    return out


def _prior_vector(prior: Vehicle) -> np.ndarray:
    lever = prior.center_of_buoyancy - prior.center_of_gravity
    return np.concatenate([prior.added_mass, prior.linear_damping, prior.quadratic_damping, [prior.buoyancy], lever,
                           prior.thrust_scale, np.ones(3)])


# -- data ------------------------------------------------------------------------------------------------------


def _pieces(run: Run) -> list[slice]:
    """Stretches of a run without a gap in its ticks (stale telemetry, a pause)."""
    dt = np.diff(run.t)
    breaks = np.flatnonzero(dt > GAP_FACTOR * np.median(dt)) + 1
    edges = np.concatenate([[0], breaks, [len(run.t)]])
    return [slice(a, b) for a, b in zip(edges[:-1], edges[1:]) if b - a > 1]


def _nominal_thrusts(run: Run, t200: T200) -> np.ndarray:
    """(N, 8) N: the bench thrust at each sent PWM (mirroring undone) and the logged voltage."""
    pushing = np.sign(run.pwm - NEUTRAL_PWM) * np.sign(run.thrusts)
    mirrored = pushing.sum(axis=0) < 0
    pwm = np.where(mirrored, 2 * NEUTRAL_PWM - run.pwm, run.pwm)
    voltage = np.round(run.voltage / VOLTAGE_RESOLUTION) * VOLTAGE_RESOLUTION
    out = np.empty_like(pwm)
    for v in np.unique(voltage):
        rows = voltage == v
        out[rows] = t200.thrust(pwm[rows], v)
    return out


def _cumulative(t: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Trapezoidal integral of y (N, ...) from t[0] to each t (N,)."""
    steps = 0.5 * (y[1:] + y[:-1]) * np.diff(t).reshape((-1,) + (1,) * (y.ndim - 1))
    return np.concatenate([np.zeros((1,) + y.shape[1:]), np.cumsum(steps, axis=0)])


def _lagged_integral(t: np.ndarray, sent: np.ndarray, u: np.ndarray, delay: float, lag: float) -> np.ndarray:
    """int_{t[0]}^{t_k} f dt at every tick (N, n), for commands u (N, n) sent at vehicle times `sent` (N,) and held
    from sent_k + delay to sent_(k+1) + delay (none before), through a first-order lag T_f f_dot = u - f of time
    constant `lag` s: int f = int u - T_f f."""
    period = np.median(np.diff(t))
    s = np.concatenate([sent, [sent[-1] + period]]) + delay     # (N+1,) hold breakpoints
    held = np.diff(s)[:, None]
    cum = np.concatenate([np.zeros((1, u.shape[1])), np.cumsum(u * held, axis=0)])   # int u at s_k
    decay = np.exp(-held / lag) if lag > 0 else np.zeros_like(held)
    f = _lag_response(u, decay)                                 # f at s_k
    k = np.clip(np.searchsorted(s, t, side="right") - 1, -1, len(t) - 1)
    before = (k < 0)[:, None]
    k = np.maximum(k, 0)
    since = (t - s[k])[:, None]
    integral = cum[k] + u[k] * since
    value = u[k] + (f[k] - u[k]) * (np.exp(-since / lag) if lag > 0 else 0.0)
    return np.where(before, 0.0, integral - lag * value)


@compiled
def _lag_response(u, decay):
    """f (N+1, n) at the hold breakpoints of a first-order lag from rest: f_(k+1) = u_k + (f_k - u_k) decay_k."""
    f = np.zeros((u.shape[0] + 1, u.shape[1]))
    for k in range(u.shape[0]):
        for j in range(u.shape[1]):
            f[k + 1, j] = u[k, j] + (f[k, j] - u[k, j]) * decay[k, 0]
    return f


def _smooth(y: np.ndarray, samples: int) -> np.ndarray:
    """Savitzky-Golay (quadratic, `samples` odd) along the first axis: zero phase, polynomials kept."""
    return savgol_filter(y, samples, SMOOTHING_ORDER, axis=0, mode="interp") if samples > SMOOTHING_ORDER + 1 else y


@dataclass(frozen=True)
class _Windows:
    """Per-window integrals (W, ...) of every term of the model, over all runs."""

    duration: np.ndarray        # (W,) s
    dnu: np.ndarray             # (W, 6) nu_b - nu_a
    nu: np.ndarray              # (W, 6) int nu
    nu_abs: np.ndarray          # (W, 6) int |nu| nu
    coriolis_unit: np.ndarray   # (W, 6, 6) [w, i] = int C(E_ii) nu nu: the Coriolis column of A_i
    coriolis_rigid: np.ndarray  # (W, 6) int C(M_RB) nu nu
    rho: np.ndarray             # (W, 3) int R^T e_z
    thrust_pos: np.ndarray      # (W, 8) int of the lagged forward bench thrust (with the delay used)
    thrust_neg: np.ndarray      # (W, 8) int of the reverse
    piece: np.ndarray           # (W,) index of the unbroken stretch the window belongs to


def _state_integrals(t: np.ndarray, eta: np.ndarray, nu: np.ndarray, a: np.ndarray, b: np.ndarray,
                     rigid: np.ndarray, samples: int) -> dict[str, np.ndarray]:
    """The state-dependent fields of `_Windows` for windows [t[a], t[b]] of one stretch, from the states smoothed
    over `samples` ticks."""
    eta, nu = _smooth(eta, samples), _smooth(nu, samples)
    units = [np.diag(np.eye(6)[i]) for i in range(6)]
    terms = np.concatenate([
        nu, np.abs(nu) * nu,
        np.stack([np.einsum("nij,nj->ni", coriolis(u, nu), nu) for u in units], axis=1).reshape(-1, 36),
        np.einsum("nij,nj->ni", coriolis(rigid, nu), nu),
        rotation(eta)[:, 2, :]], axis=1)
    cum = _cumulative(t, terms)
    integral = cum[b] - cum[a]
    return dict(duration=t[b] - t[a], dnu=nu[b] - nu[a], nu=integral[:, :6], nu_abs=integral[:, 6:12],
                coriolis_unit=integral[:, 12:48].reshape(-1, 6, 6), coriolis_rigid=integral[:, 48:54],
                rho=integral[:, 54:57])


@dataclass(frozen=True)
class _Piece:
    """An unbroken stretch of a run, and the windows it is cut into."""

    t: np.ndarray          # (N,) s, the states' times
    sent: np.ndarray       # (N,) s, when each command left (vehicle time)
    nominal: np.ndarray    # (N, 8) N, the bench thrust of each command
    reference: np.ndarray  # (N, 18)
    a: np.ndarray          # (W,) first tick of each window
    b: np.ndarray          # (W,) last tick
    samples: int           # span of the smoothing, ticks (odd; 1: none)


class _Data:
    """The runs cut into windows, as measured and as the reference asked; thrust integrals for any delay."""

    def __init__(self, runs: list[Run], prior: Vehicle, window: float, smoothing: float):
        t200 = thruster_curve(replace(prior, thrust_scale=np.ones(2)))
        self.lag = prior.thruster_time_constant
        rigid = prior.rigid_body_mass_matrix
        self.pieces: list[_Piece] = []
        measured, asked = [], []
        for run in runs:
            nominal = _nominal_thrusts(run, t200)
            for piece in _pieces(run):
                t = run.t[piece]
                period = np.median(np.diff(t))
                step = max(1, int(round(window / period)))
                a = np.arange(0, len(t) - step, step)
                if a.size == 0:
                    continue
                b = a + step
                samples = min(2 * int(round(0.5 * smoothing / period)) + 1, len(t) - 1 + len(t) % 2)
                sent = np.maximum.accumulate(t + np.clip(run.age[piece], 0.0, GAP_FACTOR * period))
                ref = run.reference[piece]
                eta_d = ref[:, :6]
                nu_d = np.linalg.solve(jacobian(eta_d), ref[:, 6:12, None])[..., 0]
                label = np.full(a.size, len(self.pieces))
                measured.append(_state_integrals(t, run.eta[piece], run.nu[piece], a, b, rigid, samples)
                                | {"piece": label})
                asked.append(_state_integrals(t, eta_d, nu_d, a, b, rigid, 1) | {"piece": label})
                self.pieces.append(_Piece(t, sent, nominal[piece], ref, a, b, samples))
        if not measured:
            raise IdentificationError("the logs hold no stretch of flight longer than one window")
        if max(np.abs(p.nominal).max() for p in self.pieces) < STILL_THRUST:
            raise IdentificationError("the thrusters never pushed in these logs: nothing to fit "
                                      "(fly missions/identify.yaml)")
        self.measured = {k: np.concatenate([m[k] for m in measured]) for k in measured[0]}
        self.asked = {k: np.concatenate([m[k] for m in asked]) for k in asked[0]}

    def _thrust(self, commands: list[np.ndarray], delay: float, smooth: bool) -> dict[str, np.ndarray]:
        pos, neg = [], []
        for p, u in zip(self.pieces, commands):
            for side, part in ((pos, np.maximum(u, 0.0)), (neg, np.minimum(u, 0.0))):
                cum = _smooth(_lagged_integral(p.t, p.sent, part, delay, self.lag), p.samples if smooth else 1)
                side.append(cum[p.b] - cum[p.a])
        return {"thrust_pos": np.concatenate(pos), "thrust_neg": np.concatenate(neg)}

    def measured_windows(self, delay: float) -> _Windows:
        """The measured windows, the bench thrust delayed by `delay` s and smoothed as the states are (the same
        linear filter on every term keeps the balance exact)."""
        return _Windows(**self.measured, **self._thrust([p.nominal for p in self.pieces], delay, True))

    def design_windows(self, delay: float) -> _Windows:
        """The reference's windows with the bench thrust actually sent: the regression's design without the sensors'
        noise, to judge what the excitation can tell apart."""
        return _Windows(**self.asked, **self._thrust([p.nominal for p in self.pieces], delay, False))

    def demand(self, vehicle: Vehicle) -> list[np.ndarray]:
        """Per stretch, the bench thrust (N, 8) `vehicle` would need to fly the reference exactly (Eq. 2.17 with
        e = 0: `tuning.feedforward`, allocated by the pseudo-inverse)."""
        allocate = np.linalg.pinv(allocation_matrix(vehicle.thruster_positions, vehicle.thruster_directions))
        commands = []
        for p in self.pieces:
            thrust = np.einsum("ij,nj->ni", allocate, feedforward(vehicle, p.reference))
            commands.append(thrust / np.where(thrust > 0, vehicle.thrust_scale[0], vehicle.thrust_scale[1]))
        return commands

    def reference_windows(self, delay: float, demand: list[np.ndarray]) -> _Windows:
        """The reference's windows with a `demand`ed thrust: the instruments, free of sensor noise."""
        return _Windows(**self.asked, **self._thrust(demand, delay, False))


# -- model -----------------------------------------------------------------------------------------------------


class _Model:
    """Both sides of the integrated balance for a parameter vector theta (layout: `_parameters`)."""

    def __init__(self, prior: Vehicle):
        self.rigid = prior.rigid_body_mass_matrix
        self.weight = prior.weight
        self.r_g = prior.center_of_gravity
        r, e = prior.thruster_positions, prior.thruster_directions
        vertical = np.abs(e[:, 2]) > 0.9
        horizontal = np.abs(e[:, 2]) < 0.1
        self.positions, self.masks = r, []
        for mask in (vertical[:, None] * [0, 1, 0], vertical[:, None] * [1, 0, 0], horizontal[:, None] * [1, 1, 0]):
            self.masks.append(mask.astype(float))
        self.b0 = allocation_matrix(r, e)
        self.b_arm = []
        for mask in self.masks:
            arm = allocation_matrix(r * mask, e)
            arm[:3] = 0.0
            self.b_arm.append(arm)

    def _matrix(self, arms: np.ndarray) -> np.ndarray:
        return self.b0 + sum((s - 1.0) * b for s, b in zip(arms, self.b_arm))

    def sides(self, theta: np.ndarray, w: _Windows) -> tuple[np.ndarray, np.ndarray]:
        """(model side, thrust side), each (W, 6), as mean force over each window (N, N m)."""
        A, Dl, Dq = theta[0:6], theta[6:12], theta[12:18]
        buoyancy, lever = theta[18], theta[19:22]
        k_fwd, k_rev, arms = theta[22], theta[23], theta[24:27]
        lhs = (np.einsum("wj,ij->wi", w.dnu, self.rigid) + A * w.dnu + np.einsum("wpi,p->wi", w.coriolis_unit, A)
               + w.coriolis_rigid + Dl * w.nu + Dq * w.nu_abs)
        net = self.weight - buoyancy
        lhs[:, :3] -= net * w.rho
        lhs[:, 3:] -= np.cross(net * self.r_g - buoyancy * lever, w.rho)
        rhs = np.einsum("wj,ij->wi", k_fwd * w.thrust_pos + k_rev * w.thrust_neg, self._matrix(arms))
        d = w.duration[:, None]
        return lhs / d, rhs / d

    def jacobian(self, theta: np.ndarray, w: _Windows) -> np.ndarray:
        """d(model side - thrust side)/d theta, (W, 6, 27): exact, the model being at most bilinear."""
        buoyancy, lever = theta[18], theta[19:22]
        k_fwd, k_rev, arms = theta[22], theta[23], theta[24:27]
        n = len(w.duration)
        jac = np.zeros((n, 6, len(theta)))
        dof = np.arange(6)
        jac[:, dof, dof] = w.dnu
        jac[:, :, 0:6] += np.swapaxes(w.coriolis_unit, 1, 2)
        jac[:, dof, 6 + dof] = w.nu
        jac[:, dof, 12 + dof] = w.nu_abs
        jac[:, :3, 18] = w.rho
        jac[:, 3:, 18] = np.cross(self.r_g + lever, w.rho)
        for j in range(3):
            jac[:, 3:, 19 + j] = buoyancy * np.cross(np.eye(3)[j], w.rho)
        matrix = self._matrix(arms)
        jac[:, :, 22] = -np.einsum("wj,ij->wi", w.thrust_pos, matrix)
        jac[:, :, 23] = -np.einsum("wj,ij->wi", w.thrust_neg, matrix)
        thrust = k_fwd * w.thrust_pos + k_rev * w.thrust_neg
        for s, b in enumerate(self.b_arm):
            jac[:, :, 24 + s] = -np.einsum("wj,ij->wi", thrust, b)
        return jac / w.duration[:, None, None]

    def positions_for(self, arms: np.ndarray) -> np.ndarray:
        return self.positions * (1.0 + sum((s - 1.0) * m for s, m in zip(arms, self.masks)))


# -- fit -------------------------------------------------------------------------------------------------------


@dataclass
class _Fit:
    theta: np.ndarray
    cost: float                 # sum of the weighted residuals squared
    residual: np.ndarray        # (W, 6) unweighted
    jacobian: np.ndarray        # (W * 6, free) of the weighted residuals, measured windows
    instruments: np.ndarray     # (W * 6, free) the same on the reference's windows


def _fit(model: _Model, w: _Windows, theta0: np.ndarray, free: np.ndarray, scale: np.ndarray,
         instruments=None) -> _Fit:
    """The free parameters (the others held at theta0); r: the residuals on the measured windows, weighted by
    1 / scale (6,) per DOF; J its Jacobian.

    First least squares, min |r|^2. Then, given `instruments` (theta -> the reference's windows flown by the model
    theta), the instrumental-variables solution Z^T r = 0 from there, Z being the model's Jacobian on those windows.
    The reference is free of the sensors' noise but the vehicle follows it, so Z correlates with the true regressors
    and not with the noise in the measured ones. On noisy closed-loop data least squares is biased both ways: noise
    in the regressors pulls added mass and damping toward zero (errors in variables), and the controller's reaction
    to that noise, which is in the thrust, pulls them toward its own gains; instrumental variables are not."""
    index = np.flatnonzero(free)

    def weighted(th, windows):
        return (model.jacobian(th, windows)[:, :, index] / scale[None, :, None]).reshape(-1, index.size)

    def residual(th):
        lhs, rhs = model.sides(th, w)
        return ((lhs - rhs) / scale).ravel()

    theta = _levenberg_marquardt(residual, lambda th: weighted(th, w), np.maximum(theta0, LOWER), index)
    z = weighted(theta, w)
    if instruments is not None:
        z = weighted(theta, instruments(theta))
        theta = _gauss_newton(lambda th: np.einsum("ij,i->j", z, residual(th)),
                              lambda th: np.einsum("ij,ik->jk", z, weighted(th, w)), theta, index)
    r = residual(theta).reshape(-1, 6)
    return _Fit(theta, float(np.sum(r**2)), r * scale, weighted(theta, w), z)


def _gauss_newton(function, jacobian, theta: np.ndarray, index: np.ndarray) -> np.ndarray:
    """theta with function(theta) = 0 over theta[index] (as many equations as unknowns), by Newton steps halved
    while they do not reduce |function|; unbounded (the caller holds what crosses a bound)."""
    theta = theta.copy()
    f = function(theta)
    for _ in range(MAX_ITERATIONS):
        step = np.linalg.solve(jacobian(theta), -f)
        for _ in range(20):
            trial = theta.copy()
            trial[index] += step
            f_trial = function(trial)
            if f_trial @ f_trial < f @ f:
                break
            step *= 0.5
        else:
            break
        converged = np.all(np.abs(trial[index] - theta[index]) <= 1e-10 * np.maximum(np.abs(theta[index]), 1e-3))
        theta, f = trial, f_trial
        if converged:
            break
    return theta


def _levenberg_marquardt(function, jacobian, theta: np.ndarray, index: np.ndarray) -> np.ndarray:
    """theta with theta[index] minimising |function(theta)|^2, theta[index] >= LOWER[index] (a parameter at its
    bound that the gradient pushes further out is held there for the step). Normal equations by einsum: small,
    and immune to a loaded machine's BLAS thread contention."""
    theta = theta.copy()
    f = function(theta)
    cost = float(f @ f)
    damping = 1e-3
    for _ in range(MAX_ITERATIONS):
        jac = jacobian(theta)
        gradient = np.einsum("ij,i->j", jac, f)
        normal = np.einsum("ij,ik->jk", jac, jac)
        movable = ~((theta[index] <= LOWER[index]) & (gradient > 0))
        h = normal[np.ix_(movable, movable)]
        while True:
            step = np.zeros(index.size)
            step[movable] = np.linalg.solve(h + damping * np.diag(np.diag(h) + 1e-30), -gradient[movable])
            trial = theta.copy()
            trial[index] = np.maximum(theta[index] + step, LOWER[index])
            f_trial = function(trial)
            cost_trial = float(f_trial @ f_trial)
            if cost_trial <= cost or damping > 1e12:
                break
            damping *= 10.0
        if cost_trial > cost:
            break
        converged = cost - cost_trial <= 1e-12 * cost
        theta, f, cost = trial, f_trial, cost_trial
        damping = max(damping / 10.0, 1e-12)
        if converged:
            break
    return theta


def _covariance(fit: _Fit, scale: np.ndarray, piece: np.ndarray) -> np.ndarray:
    """Covariance of the free parameters, s^2 (Z^T J)^-1 Z^T Z (J^T Z)^-1 (instrumental variables), widened by
    (1 + r1) / (1 - r1) for a lag-1 correlation r1 > 0 of the weighted residuals between consecutive windows of a
    stretch (fewer independent windows than windows)."""
    weighted = fit.residual / scale
    n, p = weighted.size, fit.jacobian.shape[1]
    s2 = float(np.sum(weighted**2)) / max(n - p, 1)
    same = piece[1:] == piece[:-1]
    r1 = float(np.sum(weighted[1:][same] * weighted[:-1][same]) / np.sum(weighted**2))
    widen = (1 + r1) / (1 - r1) if 0 < r1 < 1 else 1.0
    return _sandwich(fit.jacobian, fit.instruments) * s2 * widen


def _sandwich(jac: np.ndarray, z: np.ndarray) -> np.ndarray:
    """(Z^T J)^-1 Z^T Z (J^T Z)^-1: the instrumental-variables covariance per unit residual variance."""
    inverse = np.linalg.inv(np.einsum("ij,ik->jk", z, jac))
    return inverse @ np.einsum("ij,ik->jk", z, z) @ inverse.T


def _collinearity(jacobian: np.ndarray) -> tuple[np.ndarray | None, np.ndarray, np.ndarray]:
    """(blind, vif, correlation) of the regressors (the Jacobian's columns scaled to unit length): the parameter
    direction the data cannot see at all (or None), each parameter's variance inflation factor 1 / (1 - R_j^2)
    (R_j: how well the other columns reproduce its own) and the parameters' correlations."""
    norms = np.linalg.norm(jacobian, axis=0)
    p = norms.size
    if np.any(norms == 0):
        return (norms == 0).astype(float), np.full(p, np.inf), np.eye(p)
    scaled = jacobian / norms
    normal = np.einsum("ij,ik->jk", scaled, scaled)
    eigenvalues, vectors = np.linalg.eigh(normal)               # singular values squared, ascending
    if eigenvalues[0] < STRUCTURAL**2 * eigenvalues[-1]:
        return vectors[:, 0], np.full(p, np.inf), np.eye(p)
    inverse = np.linalg.inv(normal)
    vif = np.diag(inverse)
    return None, vif, inverse / np.sqrt(np.outer(vif, vif))


def _culprit(candidates: list[str], rank: dict[str, float]) -> str:
    """Which of the parameters to keep at the prior: a moment arm if any (a ruler measures them), else the worst."""
    return next((n for n in ARM_ORDER if n in candidates), max(candidates, key=lambda n: rank[n]))


def identify(runs: list[Run], prior: Vehicle, net_buoyancy: float | None = None,
             window: float = WINDOW, smoothing: float = SMOOTHING) -> Identification:
    """Fit the model's unknowns to `runs`, starting from (and falling back on) `prior`; see the module docstring.

    net_buoyancy: the vehicle's measured weight in water, B - W in N (positive: it floats), or None to keep the
    prior's forward thrust scale instead. IdentificationError when the runs are too short to fit anything."""
    duration = sum(float(r.t[-1] - r.t[0]) for r in runs)
    if duration < MIN_DURATION:
        raise IdentificationError(f"only {duration:.1f} s of flight in the logs; identify needs at least "
                                  f"{MIN_DURATION:g} s (fly missions/identify.yaml)")
    params = _parameters(prior)
    names = [p.name for p in params]
    theta0 = _prior_vector(prior)
    status = {}
    if net_buoyancy is None:
        status["thrust_scale.forward"] = ("prior: motion shows forces only relative to the thrust, so the thrusters' "
                                          "bench data set the level (give --net-buoyancy to fit it)")
    else:
        theta0[names.index("buoyancy")] = prior.weight + net_buoyancy
        status["buoyancy"] = f"given: net buoyancy {net_buoyancy:+.2f} N (--net-buoyancy)"
    data = _Data(runs, prior, window, smoothing)
    model = _Model(prior)

    def free_mask() -> np.ndarray:
        return np.array([n not in status for n in names])

    _structure(model, data, prior, theta0, params, status, free_mask)
    if not free_mask().any():
        raise IdentificationError("nothing in the logs can be identified: the vehicle was not excited "
                                  "(fly missions/identify.yaml)")
    period = float(np.median(np.concatenate([np.diff(r.t) for r in runs])))
    first = data.measured_windows(0.0)
    scale = np.maximum(np.sqrt(np.mean(model.sides(theta0, first)[1] ** 2, axis=0)), 1e-6)

    def instruments_at(delay: float):
        return lambda th: data.reference_windows(delay, data.demand(_vehicle(prior, th, model)))

    delay = _delay(model, data, prior, theta0, free_mask(), scale, period)
    windows, instruments = data.measured_windows(delay), instruments_at(delay)
    best = _fit(model, windows, theta0, free_mask(), scale, instruments)
    scale = np.maximum(np.sqrt(np.mean(best.residual**2, axis=0)), 1e-9)
    theta = best.theta
    while True:
        free = free_mask()
        if not free.any():
            raise IdentificationError("nothing in the logs can be identified: the vehicle was not excited "
                                      "(fly missions/identify.yaml)")
        fit = _fit(model, windows, np.where(free, theta, theta0), free, scale, instruments)
        index = np.flatnonzero(free)
        half = Z95 * np.sqrt(np.maximum(np.diag(_covariance(fit, scale, windows.piece)), 0.0))
        allowed = np.array([max(params[i].precision * max(abs(fit.theta[i]), abs(theta0[i])), params[i].floor)
                            for i in index])
        worst = int(np.argmax(half / allowed))
        if half[worst] > allowed[worst]:
            i = index[worst]
            status[names[i]] = (f"prior: the data do not pin it down (fitted {fit.theta[i]:.4g} "
                                f"+/- {half[worst]:.2g} {params[i].unit})".replace(" )", ")"))
            continue
        below = [i for i in index if fit.theta[i] < LOWER[i]]
        if below:
            i = min(below, key=lambda j: fit.theta[j] / max(abs(theta0[j]), params[j].floor))
            theta0[i] = LOWER[i]
            status[names[i]] = f"bound: fitted {fit.theta[i]:.3g} {params[i].unit}, below {LOWER[i]:g}: held there"
            continue
        theta = fit.theta
        break
    widths = dict(zip(index, half))
    estimates = tuple(Estimate(p.name, p.unit, float(theta[i]), float(_prior_vector(prior)[i]),
                               float(widths.get(i, np.nan)), status.get(p.name, "fitted"))
                      for i, p in enumerate(params))
    lhs, rhs = model.sides(theta, windows)
    fits = tuple(DofFit(d, float(1.0 - np.sum((lhs[:, i] - rhs[:, i]) ** 2) / np.sum((rhs[:, i] - rhs[:, i].mean())
                                                                                        ** 2)),
                        float(np.sqrt(np.mean((lhs[:, i] - rhs[:, i]) ** 2))), "N" if i < 3 else "N m")
                 for i, d in enumerate(DOFS))
    return Identification(_vehicle(prior, theta, model), estimates, fits, float(delay), int(len(windows.duration)),
                          duration)


def _delay(model: _Model, data: _Data, prior: Vehicle, theta0: np.ndarray, free: np.ndarray, scale: np.ndarray,
           period: float) -> float:
    """The command-to-thrust delay (s): where the moment condition z_d^T r = 0 holds, z_d being how the thrust side
    changes with the delay on the reference (the instrument of the delay) and r the residuals of the fit at that
    delay. Tried on a grid of DELAY_STEPS over two control periods, the zero interpolated between its points.
    (Not the delay of least residual: the controller's reaction to sensor noise is in the thrust, so the residual
    is smallest at a delay that lines that reaction up with the noise.)"""
    delays = np.linspace(0.0, 2.0 * period, DELAY_STEPS)
    h = 0.25 * (delays[1] - delays[0])
    moments = []
    for d in delays:
        fit = _fit(model, data.measured_windows(d), theta0, free, scale,
                   lambda th, d=d: data.reference_windows(d, data.demand(_vehicle(prior, th, model))))
        demand = data.demand(_vehicle(prior, fit.theta, model))
        ahead, behind = data.reference_windows(d + h, demand), data.reference_windows(d - h, demand)
        change = (model.sides(fit.theta, ahead)[1] - model.sides(fit.theta, behind)[1]) / scale
        moments.append(float(np.sum(change * fit.residual / scale)) / float(np.sqrt(np.sum(change**2))))
    moments = np.array(moments)
    crossing = np.flatnonzero(np.sign(moments[:-1]) * np.sign(moments[1:]) <= 0)
    if crossing.size == 0:
        return float(delays[np.argmin(np.abs(moments))])
    k = crossing[0]
    return float(delays[k] + (delays[k + 1] - delays[k]) * moments[k] / (moments[k] - moments[k + 1]))


def _structure(model: _Model, data: _Data, prior: Vehicle, theta0: np.ndarray, params: list[_Parameter],
               status: dict[str, str], free_mask) -> None:
    """Keep at the prior what the excitation cannot show whatever the noise, judged on the flight the prior model
    would need to fly the logged reference (noise-free regressors, each DOF weighted by its force): a parameter the
    reference never exercises; then, one at a time, a parameter direction the data cannot see at all, or a parameter
    whose variance inflation exceeds VIF_MAX."""
    names = [p.name for p in params]
    reference = data.reference_windows(0.0, data.demand(_vehicle(prior, theta0, model)))
    force = np.sqrt(np.mean(model.sides(theta0, reference)[1] ** 2, axis=0))
    force = np.maximum(force, 1e-3 * force.max())
    design = model.jacobian(theta0, reference) / force[None, :, None]
    size = np.array([max(abs(v), p.floor, p.precision) for v, p in zip(theta0, params)])
    effect = np.linalg.norm(design.reshape(-1, len(names)), axis=0) * size      # each parameter's share of the forces
    for i in np.flatnonzero(free_mask() & (effect < NOT_EXCITED * effect.max())):
        status[names[i]] = "prior: not excited in these logs"
    while (free := free_mask()).any():
        index = np.flatnonzero(free)
        blind, vif, correlation = _collinearity(design[:, :, index].reshape(-1, index.size))
        named = [names[i] for i in index]
        if blind is not None:
            loading = dict(zip(named, np.abs(blind) / np.abs(blind).max()))
            involved = sorted((n for n, v in loading.items() if v > 0.3), key=lambda n: -loading[n])
            culprit = _culprit(involved, loading)
            others = [n for n in involved if n != culprit]
            status[culprit] = "prior: not separable from " + ", ".join(others[:4]) + (", ..." if others[4:] else "")
        elif vif.max() > VIF_MAX:
            ranked = dict(zip(named, vif))
            culprit = _culprit([n for n, v in ranked.items() if v > VIF_MAX], ranked)
            row = correlation[named.index(culprit)]
            partners = [named[j] for j in np.argsort(-np.abs(row))[1:4] if abs(row[j]) > 0.5]
            status[culprit] = (f"prior: collinear with {', '.join(partners) or 'the rest'} (variance inflation "
                               f"{ranked[culprit]:.0f}): the data cannot tell them apart")
        else:
            return


def _vehicle(prior: Vehicle, theta: np.ndarray, model: _Model) -> Vehicle:
    """The prior with the parameter vector's values in (volume from B, r_b from the lever, scaled arms)."""
    return replace(
        prior,
        added_mass=theta[0:6].copy(), linear_damping=theta[6:12].copy(), quadratic_damping=theta[12:18].copy(),
        volume=float(theta[18] / (prior.water_density * prior.gravity)),
        center_of_buoyancy=prior.center_of_gravity + theta[19:22],
        thrust_scale=theta[22:24].copy(), thruster_positions=model.positions_for(theta[24:27]),
    )
