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

from rov_mav.model.dynamics import coriolis, rotation
from rov_mav.model.thrusters import NEUTRAL_PWM, T200, allocation_matrix, thruster_curve
from rov_mav.model.vehicle import Vehicle

DOFS = ("surge", "sway", "heave", "roll", "pitch", "yaw")
WINDOW = 0.4                  # s, length of the integration windows
MIN_DURATION = 30.0           # s of flight in all runs together
GAP_FACTOR = 3.0              # a tick further than this many median periods from the last starts a new piece
DELAY_STEPS = 9               # delays tried: 0, 1/4, ..., 2 control periods
RELATIVE_PRECISION = 0.1      # a fitted value is kept when its 95 % CI half-width is within 10 % of its size
FLOOR_FRACTION = 0.02         # ... or below this fraction of the rigid body's mass (inertia) in the DOF's units
STRUCTURAL = 1e-6             # singular value ratio of the column-scaled Jacobian below which a direction is blind
VIF_MAX = 100.0               # variance inflation beyond which a parameter is too collinear with others to fit
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
    floor: float


def _parameters(prior: Vehicle) -> list[_Parameter]:
    rigid = np.diag(prior.rigid_body_mass_matrix)
    units = [("kg", "N s/m", "N s^2/m^2")] * 3 + [("kg m^2", "N m s/rad", "N m s^2/rad^2")] * 3
    out = [_Parameter(f"added_mass.{d}", units[i][0], FLOOR_FRACTION * rigid[i]) for i, d in enumerate(DOFS)]
    out += [_Parameter(f"linear_damping.{d}", units[i][1], FLOOR_FRACTION * rigid[i]) for i, d in enumerate(DOFS)]
    out += [_Parameter(f"quadratic_damping.{d}", units[i][2], FLOOR_FRACTION * rigid[i]) for i, d in enumerate(DOFS)]
    out += [_Parameter("buoyancy", "N", 1e-3 * prior.weight)]
    out += [_Parameter(f"lever.{a}", "m", 5e-4) for a in "xyz"]
    out += [_Parameter("thrust_scale.forward", "", 0.01), _Parameter("thrust_scale.reverse", "", 0.01)]
    out += [_Parameter(name, "", 0.01) for name in ARM_ORDER]
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
    out = np.empty_like(pwm)
    for v in np.unique(run.voltage):
        rows = run.voltage == v
        out[rows] = t200.thrust(pwm[rows], v)
    return out


def _cumulative(t: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Trapezoidal integral of y (N, ...) from t[0] to each t (N,)."""
    steps = 0.5 * (y[1:] + y[:-1]) * np.diff(t).reshape((-1,) + (1,) * (y.ndim - 1))
    return np.concatenate([np.zeros((1,) + y.shape[1:]), np.cumsum(steps, axis=0)])


def _lagged_integral(t: np.ndarray, u: np.ndarray, a: np.ndarray, b: np.ndarray, delay: float,
                     lag: float) -> np.ndarray:
    """int_{t[a]}^{t[b]} f dt (W, n) for commands u (N, n) held from t_k + delay to t_(k+1) + delay (none before),
    through a first-order lag T_f f_dot = u - f of time constant `lag` s: int f = int u - T_f (f(t_b) - f(t_a))."""
    period = np.median(np.diff(t))
    s = np.concatenate([t, [t[-1] + period]]) + delay           # (N+1,) hold breakpoints
    held = np.diff(s)[:, None]
    cum = np.concatenate([np.zeros((1, u.shape[1])), np.cumsum(u * held, axis=0)])   # int u at s_k
    decay = np.exp(-held / lag) if lag > 0 else np.zeros_like(held)
    f = np.zeros((len(s), u.shape[1]))                          # f at s_k
    for k in range(len(t)):
        f[k + 1] = u[k] + (f[k] - u[k]) * decay[k]

    def at(times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        k = np.clip(np.searchsorted(s, times, side="right") - 1, -1, len(t) - 1)
        since = times - s[np.maximum(k, 0)]
        before = k < 0
        uk = np.where(before[:, None], 0.0, u[np.maximum(k, 0)])
        integral = np.where(before[:, None], 0.0, cum[np.maximum(k, 0)] + uk * since[:, None])
        fk = np.where(before[:, None], 0.0, f[np.maximum(k, 0)])
        value = uk + (fk - uk) * (np.exp(-since / lag)[:, None] if lag > 0 else 0.0)
        return integral, np.where(before[:, None], 0.0, value)

    (ua, fa), (ub, fb) = at(t[a]), at(t[b])
    return ub - ua - lag * (fb - fa)


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


class _Data:
    """The runs cut into windows; the thrust integrals are recomputed for each delay tried."""

    def __init__(self, runs: list[Run], prior: Vehicle, window: float):
        t200 = thruster_curve(replace(prior, thrust_scale=np.ones(2)))
        self.lag = prior.thruster_time_constant
        rigid = prior.rigid_body_mass_matrix
        units = [np.diag(np.eye(6)[i]) for i in range(6)]
        self.pieces = []                     # (t, u_nominal, a, b) per unbroken stretch
        parts = []
        for run in runs:
            nominal = _nominal_thrusts(run, t200)
            for piece in _pieces(run):
                t, nu, eta = run.t[piece], run.nu[piece], run.eta[piece]
                step = max(1, int(round(window / np.median(np.diff(t)))))
                a = np.arange(0, len(t) - step, step)
                if a.size == 0:
                    continue
                b = a + step
                terms = np.concatenate([
                    nu, np.abs(nu) * nu,
                    np.stack([np.einsum("nij,nj->ni", coriolis(u, nu), nu) for u in units], axis=1).reshape(-1, 36),
                    np.einsum("nij,nj->ni", coriolis(rigid, nu), nu),
                    rotation(eta)[:, 2, :]], axis=1)
                cum = _cumulative(t, terms)
                integral = cum[b] - cum[a]
                parts.append((t[b] - t[a], nu[b] - nu[a], integral, np.full(a.size, len(self.pieces))))
                self.pieces.append((t, nominal[piece], a, b))
        if not parts:
            raise IdentificationError("the logs hold no stretch of flight longer than one window")
        duration, dnu, integral, piece = (np.concatenate(p) for p in zip(*parts))
        self.base = dict(duration=duration, dnu=dnu, nu=integral[:, :6], nu_abs=integral[:, 6:12],
                         coriolis_unit=integral[:, 12:48].reshape(-1, 6, 6), coriolis_rigid=integral[:, 48:54],
                         rho=integral[:, 54:57], piece=piece)

    def windows(self, delay: float) -> _Windows:
        pos, neg = [], []
        for t, u, a, b in self.pieces:
            pos.append(_lagged_integral(t, np.maximum(u, 0.0), a, b, delay, self.lag))
            neg.append(_lagged_integral(t, np.minimum(u, 0.0), a, b, delay, self.lag))
        return _Windows(thrust_pos=np.concatenate(pos), thrust_neg=np.concatenate(neg), **self.base)


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
    cost: float
    residual: np.ndarray        # (W, 6) unweighted
    jacobian: np.ndarray        # (W * 6, free) of the weighted residuals


def _fit(model: _Model, w: _Windows, theta0: np.ndarray, free: np.ndarray, scale: np.ndarray) -> _Fit:
    """Weighted least squares over the free parameters (the others held at theta0), scale (6,) per DOF:
    Levenberg-Marquardt on the normal equations, the lower bounds kept by an active set (a parameter at its bound
    that the gradient pushes further out is held there for the step)."""
    theta = np.maximum(theta0, LOWER)
    index = np.flatnonzero(free)

    def evaluate(th):
        lhs, rhs = model.sides(th, w)
        r = ((lhs - rhs) / scale).ravel()
        return r, float(np.einsum("i,i->", r, r))

    def weighted_jacobian(th):
        return (model.jacobian(th, w)[:, :, index] / scale[None, :, None]).reshape(-1, index.size)

    r, cost = evaluate(theta)
    damping = 1e-3
    for _ in range(MAX_ITERATIONS):
        jac = weighted_jacobian(theta)
        gradient = np.einsum("ij,i->j", jac, r)
        normal = np.einsum("ij,ik->jk", jac, jac)      # einsum, not BLAS: small, and immune to thread contention
        movable = ~((theta[index] <= LOWER[index]) & (gradient > 0))
        while True:
            step = np.zeros(index.size)
            h = normal[np.ix_(movable, movable)]
            step[movable] = np.linalg.solve(h + damping * np.diag(np.diag(h) + 1e-30), -gradient[movable])
            trial = theta.copy()
            trial[index] = np.maximum(theta[index] + step, LOWER[index])
            r_trial, cost_trial = evaluate(trial)
            if cost_trial <= cost:
                break
            damping *= 10.0
            if damping > 1e12:
                break
        if cost_trial > cost:
            break
        converged = cost - cost_trial <= 1e-12 * cost
        theta, r, cost = trial, r_trial, cost_trial
        damping = max(damping / 10.0, 1e-12)
        if converged:
            break
    lhs, rhs = model.sides(theta, w)
    return _Fit(theta, cost, lhs - rhs, weighted_jacobian(theta))


def _covariance(fit: _Fit, scale: np.ndarray, piece: np.ndarray) -> np.ndarray:
    """Covariance of the free parameters: (J^T J)^-1 s^2, widened by (1 + r1) / (1 - r1) for a lag-1 correlation
    r1 > 0 of the weighted residuals between consecutive windows of a stretch (fewer independent windows)."""
    weighted = fit.residual / scale
    n, p = weighted.size, fit.jacobian.shape[1]
    s2 = float(np.sum(weighted**2)) / max(n - p, 1)
    same = piece[1:] == piece[:-1]
    r1 = float(np.sum(weighted[1:][same] * weighted[:-1][same]) / np.sum(weighted**2))
    widen = (1 + r1) / (1 - r1) if 0 < r1 < 1 else 1.0
    return np.linalg.pinv(fit.jacobian.T @ fit.jacobian) * s2 * widen


def _collinearity(jacobian: np.ndarray) -> tuple[np.ndarray | None, np.ndarray, np.ndarray]:
    """(blind, vif, correlation) of the column-scaled Jacobian: the direction the fit cannot see at all (or None),
    each parameter's variance inflation factor 1 / (1 - R_j^2) (R_j: how well the other columns reproduce its own)
    and the parameters' correlation matrix."""
    norms = np.linalg.norm(jacobian, axis=0)
    if np.any(norms == 0):
        return (norms == 0).astype(float), np.full(norms.size, np.inf), np.eye(norms.size)
    scaled = jacobian / norms
    normal = np.einsum("ij,ik->jk", scaled, scaled)
    eigenvalues, vectors = np.linalg.eigh(normal)               # singular values squared, ascending
    if eigenvalues[0] < STRUCTURAL**2 * eigenvalues[-1]:
        return vectors[:, 0], np.full(norms.size, np.inf), np.eye(norms.size)
    inverse = np.linalg.inv(normal)
    vif = np.diag(inverse)
    return None, vif, inverse / np.sqrt(np.outer(vif, vif))


def _culprit(candidates: list[str], rank: dict[str, float]) -> str:
    """Which of the parameters to keep at the prior: a moment arm if any (a ruler measures them), else the worst."""
    return next((n for n in ARM_ORDER if n in candidates), max(candidates, key=lambda n: rank[n]))


def identify(runs: list[Run], prior: Vehicle, net_buoyancy: float | None = None,
             window: float = WINDOW) -> Identification:
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
        status["thrust_scale.forward"] = ("prior: the level of all forces is set by the thrusters' bench data "
                                          "(give --net-buoyancy to fit it)")
    else:
        theta0[names.index("buoyancy")] = prior.weight + net_buoyancy
        status["buoyancy"] = f"given: weight in water {-net_buoyancy:+.2f} N (--net-buoyancy)"
    data = _Data(runs, prior, window)
    model = _Model(prior)
    period = float(np.median(np.concatenate([np.diff(r.t) for r in runs])))

    def free_mask() -> np.ndarray:
        return np.array([n not in status for n in names])

    first = data.windows(0.0)
    scale = np.maximum(np.sqrt(np.mean(model.sides(theta0, first)[1] ** 2, axis=0)), 1e-6)
    delays = np.linspace(0.0, 2.0 * period, DELAY_STEPS)
    trials = [(_fit(model, data.windows(d), theta0, free_mask(), scale), d) for d in delays]
    best, delay = min(trials, key=lambda trial: trial[0].cost)
    windows = data.windows(delay)
    scale = np.maximum(np.sqrt(np.mean(best.residual**2, axis=0)), 1e-9)
    theta = best.theta
    while True:
        free = free_mask()
        if not free.any():
            raise IdentificationError("nothing in the logs can be identified: the vehicle was not excited "
                                      "(fly missions/identify.yaml)")
        start = np.where(free, theta, theta0)
        fit = _fit(model, windows, start, free, scale)
        index = np.flatnonzero(free)
        blind, vif, correlation = _collinearity(fit.jacobian)
        if blind is not None:
            loading = dict(zip((names[i] for i in index), np.abs(blind) / np.abs(blind).max()))
            involved = [n for n, v in loading.items() if v > 0.3]
            culprit = _culprit(involved, loading)
            others = ", ".join(n for n in involved if n != culprit) or "nothing (not excited)"
            status[culprit] = f"prior: not separable from {others}"
            continue
        if vif.max() > VIF_MAX:
            ranked = dict(zip((names[i] for i in index), vif))
            culprit = _culprit([n for n, v in ranked.items() if v > VIF_MAX], ranked)
            row = correlation[[names[i] for i in index].index(culprit)]
            partners = [names[index[j]] for j in np.argsort(-np.abs(row))[1:4] if abs(row[j]) > 0.5]
            status[culprit] = (f"prior: collinear with {', '.join(partners) or 'the rest'} (variance inflation "
                               f"{ranked[culprit]:.0f}): the data cannot tell them apart")
            continue
        half = Z95 * np.sqrt(np.maximum(np.diag(_covariance(fit, scale, windows.piece)), 0.0))
        allowed = np.array([max(RELATIVE_PRECISION * max(abs(fit.theta[i]), abs(theta0[i])), params[i].floor)
                            for i in index])
        worst = int(np.argmax(half / allowed))
        if half[worst] > allowed[worst]:
            i = index[worst]
            status[names[i]] = (f"prior: the data do not pin it down (fitted {fit.theta[i]:.4g} "
                                f"+/- {half[worst]:.2g} {params[i].unit})".replace(" )", ")"))
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


def _vehicle(prior: Vehicle, theta: np.ndarray, model: _Model) -> Vehicle:
    """The prior with the parameter vector's values in (volume from B, r_b from the lever, scaled arms)."""
    return replace(
        prior,
        added_mass=theta[0:6].copy(), linear_damping=theta[6:12].copy(), quadratic_damping=theta[12:18].copy(),
        volume=float(theta[18] / (prior.water_density * prior.gravity)),
        center_of_buoyancy=prior.center_of_gravity + theta[19:22],
        thrust_scale=theta[22:24].copy(), thruster_positions=model.positions_for(theta[24:27]),
    )
