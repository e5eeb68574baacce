"""System identification: the vehicle model fitted to flown runs (`rov-mav identify`). Pure numpy/scipy.

The regression is `force_balance`'s: the report's Eq. 2.7 integrated over windows, with the unknowns theta (added
mass, linear and quadratic damping, buoyancy and its lever r_b - r_g, the thrust scale each way, three moment arms,
the horizontal thrusters' height and their scale relative to the vertical ones);
mass, inertia and the centre of gravity are the prior's. Solved jointly over the six DOFs (they share A through the
Coriolis terms, the thrust scales through tau, lambda_z through roll and pitch), each DOF weighted by its residual:

- instrumental variables, from a least-squares start: the instruments are the model's regressors on the reference
  the controller flew, with the thrust the model would need there. The reference carries none of the sensors'
  noise but the vehicle follows it. Least squares on noisy closed-loop data is biased both ways (noise in the
  regressors pulls added mass and damping toward zero; the controller's reaction to that noise, which is in the
  thrust, pulls them toward its gains); this is not.
- the command-to-thrust delay: where the instrument of the delay (how the thrust side moves with it, on the
  reference) is orthogonal to the residuals, the moment falling through zero, interpolated on a grid of two sample
  periods.
- 95 % confidence intervals from the instrumental-variables covariance, widened for the residuals' correlation from
  one window to the next.

What the data cannot tell apart, and what is done about it (each such parameter keeps the prior and says why):
- the level: scaling M, D, W - B, B lambda and the thrust by one factor leaves every equation unchanged when M_RB is
  diagonal (r_g = 0): motion shows forces only relative to the thrust. One number must come from elsewhere: the
  forward thrust scale stays the prior's (the thrusters' bench data), or a measured net buoyancy (the vehicle's
  weight in water) fixes B and frees the thrust scale. The horizontal group's scale is relative to the others' (the
  vertical thrusters'): surge, sway and yaw are driven by the horizontal thrusters alone, so only the couplings of
  surge and sway to heave, roll and pitch (the Coriolis and Munk terms of pitching while surging, rolling while
  swaying) tell it from the added mass and damping they drive.
- before fitting, on the noise-free design (the reference, the prior's thrust): parameters the reference never
  exercises; then, one at a time, a direction the data cannot see at all (rank) or a parameter too collinear with
  others (variance inflation above VIF_MAX); a moment arm goes first, a ruler measures it. The horizontal thrusters'
  scale, when surge and sway never act on heave, roll or pitch (the only link to the vertical thrusters' level).
- after fitting, one at a time: a parameter whose 95 % interval is wider than its precision (10 % of its size, 1 %
  for a moment arm and 2 % of the thrusters' reach for the horizontal ones' height, or an absolute floor scaled by
  the rigid body), then one that crossed its lower bound (held at the bound).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rov_mav.model.vehicle import Vehicle
from rov_mav.offline.identify.estimation import collinearity, gauss_newton, levenberg_marquardt, sandwich
from rov_mav.offline.identify.force_balance import Balance, Flights, IdentificationError, Run, Windows, theta_of

__all__ = ["DofFit", "Estimate", "Identification", "IdentificationError", "Run", "identify"]

DOFS = ("surge", "sway", "heave", "roll", "pitch", "yaw")
WINDOW = 0.4                  # s, length of the integration windows
SMOOTHING = 0.5               # s, span of the Savitzky-Golay filter applied to every term
MIN_DURATION = 30.0           # s of flight in all runs together
DELAY_STEPS = 5               # delays tried: 0, 1/2, ..., 2 control periods
RELATIVE_PRECISION = 0.1      # a fitted value is kept when its 95 % CI half-width is within 10 % of its size
ARM_PRECISION = 0.01          # ... 1 % for a moment arm, which a ruler measures about that well
HEIGHT_PRECISION = 0.02       # ... 2 % of the thrusters' reach for the horizontal ones' height (5 mm on a BlueROV2:
                              # 0.2 N m of roll or pitch at 40 N of thrust)
FLOOR_FRACTION = 0.02         # ... or below this fraction of the rigid body's mass (inertia) in the DOF's units
NOT_EXCITED = 1e-6            # a parameter whose forces are this small beside the largest one's is not excited
VIF_MAX = 1.0e4               # variance inflation beyond which a parameter is too collinear with others to fit
Z95 = 1.959964
ARM_ORDER = ("arm_roll", "arm_pitch", "arm_yaw", "arm_horizontal_z")
# Lower bounds of theta: added mass, damping, buoyancy and arms are not negative (the vehicle file's rules), a thrust
# scale is positive (the instruments divide by it); the lever is free.
MIN_THRUST_SCALE = 0.05
HEIGHT = 27                   # theta's index of the horizontal thrusters' g h (the next is g)
GROUP = "thrust_scale.horizontal"
COUPLING_MIN = 0.01           # the surge or sway added mass's share in heave, roll and pitch that lets GROUP be fitted
LOWER = np.concatenate([np.zeros(19), np.full(3, -np.inf), np.full(2, MIN_THRUST_SCALE), np.zeros(3), [-np.inf],
                        [MIN_THRUST_SCALE]])


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
    """What `identify` found: the vehicle, every parameter with its interval or reason, the fit per DOF."""

    vehicle: Vehicle                 # the prior with every fitted value in
    estimates: tuple[Estimate, ...]
    fits: tuple[DofFit, ...]
    delay: float                     # s, command-to-thrust delay found
    windows: int                     # integration windows used
    duration: float                  # s of flight in the logs


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
    out += [_Parameter(name, "", 0.0, ARM_PRECISION) for name in ARM_ORDER[:3]]
    reach = float(np.abs(prior.thruster_positions).max())
    out += [_Parameter("arm_horizontal_z", "m", HEIGHT_PRECISION * reach, 0.0),
            _Parameter("thrust_scale.horizontal", "", 0.01)]
    return out


@dataclass
class _Fit:
    """One solution over a set of free parameters, with what its intervals and diagnostics need."""

    theta: np.ndarray
    residual: np.ndarray        # (W, 6) unweighted
    jacobian: np.ndarray        # (W * 6, free) of the weighted residuals, measured windows
    instruments: np.ndarray     # (W * 6, free) the same on the reference's windows


def _fit(model: Balance, w: Windows, theta0: np.ndarray, free: np.ndarray, scale: np.ndarray,
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

    theta = levenberg_marquardt(residual, lambda th: weighted(th, w), np.maximum(theta0, LOWER), index, LOWER)
    z = weighted(theta, w)
    if instruments is not None:
        z = weighted(theta, instruments(theta))
        theta = gauss_newton(lambda th: np.einsum("ij,i->j", z, residual(th)),
                             lambda th: np.einsum("ij,ik->jk", z, weighted(th, w)), theta, index)
    return _Fit(theta, residual(theta).reshape(-1, 6) * scale, weighted(theta, w), z)


def _instruments(model: Balance, data: Flights, delay: float):
    """theta -> the reference's windows with the thrust the model theta would need to fly it (the instruments)."""
    return lambda theta: data.reference_windows(delay, data.demand(model.vehicle(theta)))


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
    return sandwich(fit.jacobian, fit.instruments) * s2 * widen


def _culprit(candidates: list[str], rank: dict[str, float]) -> str:
    """Which of the parameters to keep at the prior: a moment arm if any (a ruler measures them), else the worst."""
    return next((n for n in ARM_ORDER if n in candidates), max(candidates, key=lambda n: rank[n]))


def identify(runs: list[Run], prior: Vehicle, net_buoyancy: float | None = None,
             window: float = WINDOW, smoothing: float = SMOOTHING, dofs: np.ndarray | None = None) -> Identification:
    """Fit the model's unknowns to `runs`, starting from (and falling back on) `prior`; see the module docstring.

    net_buoyancy: the vehicle's measured weight in water, B - W in N (positive: it floats), or None to keep the
    prior's forward thrust scale instead. dofs: (6,) bool, the DOFs whose balance is fitted (default all); a parameter
    acting in the others only keeps the prior ("not excited"). IdentificationError when the runs are too short to
    fit anything."""
    duration = sum(float(r.t[-1] - r.t[0]) for r in runs)
    if duration < MIN_DURATION:
        raise IdentificationError(f"only {duration:.1f} s of flight in the logs; identify needs at least "
                                  f"{MIN_DURATION:g} s (fly the shipped mission identify)")
    params = _parameters(prior)
    names = [p.name for p in params]
    theta0 = theta_of(prior)
    status = {}
    if net_buoyancy is None:
        status["thrust_scale.forward"] = ("prior: motion shows forces only relative to the thrust, so the thrusters' "
                                          "bench data set the level (give --net-buoyancy to fit it)")
    else:
        theta0[names.index("buoyancy")] = prior.weight + net_buoyancy
        status["buoyancy"] = f"given: net buoyancy {net_buoyancy:+.2f} N (--net-buoyancy)"
    data = Flights(runs, prior, window, smoothing)
    model = Balance(prior)
    if dofs is not None:
        model.dofs = np.asarray(dofs, dtype=float)
        for dof in (d for d, fitted in zip(DOFS, dofs) if not fitted):
            for kind in ("added_mass", "linear_damping", "quadratic_damping"):
                status[f"{kind}.{dof}"] = f"prior: {dof} is not fitted (not excited, or not measured)"

    def free_mask() -> np.ndarray:
        model.hold_height = "arm_horizontal_z" in status      # a held height follows the fitted scale
        return np.array([n not in status for n in names])

    _structure(model, data, theta0, params, status, free_mask)
    if not free_mask().any():
        raise IdentificationError("nothing in the logs can be identified: the vehicle was not excited "
                                  "(fly the shipped mission identify)")
    period = float(np.median(np.concatenate([np.diff(r.t) for r in runs])))
    scale = np.maximum(np.sqrt(np.mean(model.sides(theta0, data.measured_windows(0.0))[1] ** 2, axis=0)), 1e-6)
    delay = _delay(model, data, theta0, free_mask(), scale, period)
    windows, instruments = data.measured_windows(delay), _instruments(model, data, delay)
    best = _fit(model, windows, theta0, free_mask(), scale, instruments)
    scale = np.maximum(np.sqrt(np.mean(best.residual**2, axis=0)), 1e-9)
    theta = best.theta
    while True:
        free = free_mask()
        if not free.any():
            raise IdentificationError("nothing in the logs can be identified: the vehicle was not excited "
                                      "(fly the shipped mission identify)")
        fit = _fit(model, windows, np.where(free, theta, theta0), free, scale, instruments)
        scale = np.maximum(np.sqrt(np.mean(fit.residual**2, axis=0)), 1e-9)   # each DOF by its residual, as fitted
        fit = _fit(model, windows, fit.theta, free, scale, instruments)
        index = np.flatnonzero(free)
        half = Z95 * np.sqrt(np.maximum(np.diag(_covariance(fit, scale, windows.piece)), 0.0))
        allowed = np.array([max(params[i].precision * max(abs(fit.theta[i]), abs(theta0[i])), params[i].floor)
                            for i in index])
        worst = int(np.argmax(half / allowed))
        if half[worst] > allowed[worst]:
            i = index[worst]
            value = f"{fit.theta[i]:.4g} +/- {half[worst]:.2g} {params[i].unit}".rstrip()
            status[names[i]] = f"prior: the data do not pin it down (fitted {value})"
            continue
        below = [i for i in index if fit.theta[i] < LOWER[i]]
        if below:
            i = min(below, key=lambda j: fit.theta[j] / max(abs(theta0[j]), params[j].floor))
            theta0[i] = LOWER[i]
            status[names[i]] = f"bound: fitted {fit.theta[i]:.3g} {params[i].unit}, below {LOWER[i]:g}: held there"
            continue
        theta = fit.theta
        break
    widths, priors = dict(zip(index, half)), theta_of(prior)
    theta[HEIGHT] = model.moment(theta)         # theta holds g h: the height is printed as h
    per = np.ones((2, len(theta)))
    per[:, HEIGHT] = theta[HEIGHT + 1], priors[HEIGHT + 1]
    estimates = tuple(Estimate(p.name, p.unit, float(theta[i] / per[0, i]), float(priors[i] / per[1, i]),
                               float(widths.get(i, np.nan) / per[0, i]), status.get(p.name, "fitted"))
                      for i, p in enumerate(params))
    return Identification(model.vehicle(theta), estimates, _fits(*model.sides(theta, windows)), float(delay),
                          int(len(windows.duration)), duration)


def _fits(model_side: np.ndarray, thrust_side: np.ndarray) -> tuple[DofFit, ...]:
    """Per DOF, the share of the thrust side's variance the model side explains (R^2) and the RMS left."""
    out = []
    for i, dof in enumerate(DOFS):
        residual = model_side[:, i] - thrust_side[:, i]
        spread = np.sum((thrust_side[:, i] - thrust_side[:, i].mean()) ** 2)
        out.append(DofFit(dof, float(1.0 - np.sum(residual**2) / spread) if spread > 0 else float("nan"),
                          float(np.sqrt(np.mean(residual**2))), "N" if i < 3 else "N m"))
    return tuple(out)


def _delay(model: Balance, data: Flights, theta0: np.ndarray, free: np.ndarray, scale: np.ndarray,
           period: float) -> float:
    """The command-to-thrust delay (s): where the moment condition z_d^T r = 0 holds, z_d being how the thrust side
    changes with the delay on the reference (the instrument of the delay) and r the residuals of the fit at that
    delay. Tried on a grid of DELAY_STEPS over two sample periods, the zero interpolated between its points.
    (Not the delay of least residual: the controller's reaction to sensor noise is in the thrust, so the residual
    is smallest at a delay that lines that reaction up with the noise.)
    Near the true delay d* the thrust side moves by (d - d*) z_d, so the moment falls through zero there: a zero it
    rises through is not the delay (on a .BIN's 10 Hz samples one appears a period or two on), and a moment already
    negative at 0 puts d* at 0 (the vehicle's own log stamps its outputs on its own clock)."""
    delays = np.linspace(0.0, 2.0 * period, DELAY_STEPS)
    h = 0.25 * (delays[1] - delays[0])
    moments = []
    for d in delays:
        fit = _fit(model, data.measured_windows(d), theta0, free, scale, _instruments(model, data, d))
        demand = data.demand(model.vehicle(fit.theta))
        ahead, behind = data.reference_windows(d + h, demand), data.reference_windows(d - h, demand)
        change = (model.sides(fit.theta, ahead)[1] - model.sides(fit.theta, behind)[1]) / scale
        moments.append(float(np.sum(change * fit.residual / scale)) / float(np.sqrt(np.sum(change**2))))
    return falling_zero(delays, np.array(moments))


def falling_zero(delays: np.ndarray, moments: np.ndarray) -> float:
    """Where `moments` (sampled at `delays`) first falls through zero, interpolated: the first delay when it is
    already at or below zero there, the last when it never falls."""
    if moments[0] <= 0.0:
        return float(delays[0])
    falling = np.flatnonzero((moments[:-1] > 0.0) & (moments[1:] <= 0.0))
    if falling.size == 0:
        return float(delays[-1])
    k = falling[0]
    return float(delays[k] + (delays[k + 1] - delays[k]) * moments[k] / (moments[k] - moments[k + 1]))


def _coupled(design: np.ndarray, names: list[str]) -> bool:
    """Whether the surge or sway added mass acts in the heave, roll or pitch balance (the vertical thrusters' DOFs)
    at least COUPLING_MIN of what it does in its own: what tells the horizontal thrusters' scale from the forces they
    drive. design: (W, 6, parameters), each DOF scaled by its force."""
    for dof, name in ((0, "added_mass.surge"), (1, "added_mass.sway")):
        column = design[:, :, names.index(name)]
        own = np.linalg.norm(column[:, dof])
        if own > 0 and np.linalg.norm(column[:, 2:5]) >= COUPLING_MIN * own:
            return True
    return False


def _structure(model: Balance, data: Flights, theta0: np.ndarray, params: list[_Parameter], status: dict[str, str],
               free_mask) -> None:
    """Keep at the prior what the excitation cannot show whatever the noise, judged on the flight the prior model
    would need to fly the logged reference (noise-free regressors, each DOF weighted by its force): a parameter the
    reference never exercises; then, one at a time, a parameter direction the data cannot see at all, or a parameter
    whose variance inflation exceeds VIF_MAX."""
    names = [p.name for p in params]
    reference = data.reference_windows(0.0, data.demand(model.vehicle(theta0)))
    force = np.sqrt(np.mean(model.sides(theta0, reference)[1] ** 2, axis=0))
    force = np.maximum(force, 1e-3 * force.max())
    design = model.jacobian(theta0, reference) / force[None, :, None]
    size = np.array([max(abs(v), p.floor, p.precision) for v, p in zip(theta0, params)])
    effect = np.linalg.norm(design.reshape(-1, len(names)), axis=0) * size      # each parameter's share of the forces
    for i in np.flatnonzero(free_mask() & (effect < NOT_EXCITED * effect.max())):
        status[names[i]] = "prior: not excited in these logs"
    if GROUP not in status and not _coupled(design, names):
        status[GROUP] = ("prior: nothing in these logs couples surge or sway to heave, roll or pitch (pitching while "
                         "surging, rolling while swaying), so the horizontal thrusters' force cannot be told from the "
                         "added mass and damping it drives")
    while (free := free_mask()).any():
        index = np.flatnonzero(free)
        blind, vif, correlation = collinearity(design[:, :, index].reshape(-1, index.size))
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
