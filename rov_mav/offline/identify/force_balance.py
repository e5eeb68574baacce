"""The vehicle's force balance integrated over windows of a flown run: the regression `rov-mav identify` solves.

The model is the report's Eq. 2.7 without disturbance (Fossen 2021, Handbook of Marine Craft Hydrodynamics and
Motion Control, 2nd ed., Ch. 6-8: rigid body and added mass, m2c Coriolis, damping, restoring forces of a submerged
vehicle; thrust configuration matrix), written with its unknowns theta:

    M nu_dot + C(nu) nu + D(nu) nu + g(eta) = tau
    M = M_RB + diag(A)                         (Eq. 2.8; M_RB from the prior's mass and inertia, which are known)
    C(nu) from M by m2c                        (ERRATA 5): linear in M, so each A_i has its own Coriolis column
    D(nu) = diag(D_l) + diag(D_q) |nu|         (Appendix I.3, Eq. 2.10)
    g(eta): force -(W - B) rho, moment -((W - B) r_g - B lambda) x rho, rho = R^T e_z, lambda = r_b - r_g
                                               (Appendix I.4; W = m g known, B and lambda unknown)
    tau = B(sigma, h) G(g) (k_fwd F+ + k_rev F-)
                                               (`thrusters.allocation_matrix`; F = the bench curve's thrust (T200
                                                data or the file's quadratic law) at the sent PWM and the logged
                                                voltage, split by sign, delayed by the link and lagged by the
                                                thrusters' time constant)

theta = [A (6), D_l (6), D_q (6), B, lambda (3), k_fwd, k_rev, sigma (3), g h, g]; B(sigma, h) is the allocation
matrix with three moment arms scaled -- the vertical thrusters' lateral arm (roll), their longitudinal arm (pitch),
the horizontal thrusters' planar arms (yaw), each touching only its own moment row -- and the horizontal thrusters
moved to the mean height h (their roll and pitch arm: a horizontal force below the origin rolls and pitches the
hull). G(g) = diag(per-thruster scale), the horizontal group's scaled to mean g: thrusters of one kind but two
mountings (or, on ArduPilot's SITL, two force laws) need not push alike per PWM. The height enters theta as the
product g h, the roll and pitch moment per newton of bench thrust: the roll and pitch balances see that product
whatever the level of the horizontal forces, which only the weaker couplings to the rigid body show (so g and h
as such would be collinear).

Integral form: over consecutive windows [t_a, t_b] of each unbroken stretch of a run,

    M (nu_b - nu_a) + int (C nu + D nu + g) dt = int tau dt,

so no velocity is differentiated and the held, lagged commands integrate exactly (int f = int u - T_f f for a
first-order lag of time constant T_f). Every term (states and thrust alike) is first smoothed by the same
Savitzky-Golay filter: a linear filter applied to every term of an exact balance keeps it exact, and the sensors'
noise in the states shrinks. The same windows are also built from the reference the controller flew (the states it
was asked to reach, and the thrust a given model would need there): free of sensor noise, they are the instruments.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

import numpy as np
from scipy.signal import savgol_filter

from rov_mav.model.dynamics import body_velocity, coriolis, rotation
from rov_mav.model.kernel import allocating
from rov_mav.model.thrusters import NEUTRAL_PWM, ThrusterMap, allocation_matrix, thruster_curve
from rov_mav.model.vehicle import Vehicle
from rov_mav.offline.tuning import feedforward

SMOOTHING_ORDER = 2
GAP_FACTOR = 3.0              # a tick further than this many median periods from the last starts a new stretch
VOLTAGE_RESOLUTION = 0.01     # V: the bench thrust is looked up at the logged voltage rounded to this
STILL_THRUST = 0.1            # N: logs whose thrusters never pushed harder than this have nothing to fit


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


def distinct(run: Run) -> Run:
    """The run with one tick per state time: of ticks that share one (a second command on the same state), the
    last, whose command is the one the vehicle held."""
    return rows(run, np.concatenate([np.diff(run.t) > 0, [True]]))


def rows(run: Run, keep: np.ndarray) -> Run:
    """The run's ticks where `keep` is true."""
    return Run(run.name, *(getattr(run, f.name)[keep] for f in fields(Run) if f.name != "name"))


def stretches(run: Run) -> list[slice]:
    """Stretches of a run without a gap in its ticks (stale telemetry, a pause)."""
    return gap_free(run.t)


def gap_free(t: np.ndarray) -> list[slice]:
    """Stretches of increasing times `t` without a gap (GAP_FACTOR median periods)."""
    dt = np.diff(t)
    breaks = np.flatnonzero(dt > GAP_FACTOR * np.median(dt)) + 1
    edges = np.concatenate([[0], breaks, [len(t)]])
    return [slice(a, b) for a, b in zip(edges[:-1], edges[1:]) if b - a > 1]


def bench_thrusts(run: Run, t200: ThrusterMap) -> np.ndarray:
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


def cumulative(t: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Trapezoidal integral of y (N, ...) from t[0] to each t (N,)."""
    steps = 0.5 * (y[1:] + y[:-1]) * np.diff(t).reshape((-1,) + (1,) * (y.ndim - 1))
    return np.concatenate([np.zeros((1,) + y.shape[1:]), np.cumsum(steps, axis=0)])


def lagged_integral(t: np.ndarray, sent: np.ndarray, u: np.ndarray, delay: float, lag: float) -> np.ndarray:
    """int_{t[0]}^{t_k} f dt at every tick (N, n), for commands u (N, n) sent at vehicle times `sent` (N,) and held
    from sent_k + delay to sent_(k+1) + delay (none before), through a first-order lag T_f f_dot = u - f of time
    constant `lag` s: int f = int u - T_f f."""
    period = np.median(np.diff(t))
    s = np.concatenate([sent, [sent[-1] + period]]) + delay     # (N+1,) hold breakpoints
    held = np.diff(s)[:, None]
    cum = np.concatenate([np.zeros((1, u.shape[1])), np.cumsum(u * held, axis=0)])   # int u at s_k
    decay = np.exp(-held / lag) if lag > 0 else np.zeros_like(held)
    f = lag_response(u, decay)                                 # f at s_k
    k = np.clip(np.searchsorted(s, t, side="right") - 1, -1, len(t) - 1)
    before = (k < 0)[:, None]
    k = np.maximum(k, 0)
    since = (t - s[k])[:, None]
    integral = cum[k] + u[k] * since
    value = u[k] + (f[k] - u[k]) * (np.exp(-since / lag) if lag > 0 else 0.0)
    return np.where(before, 0.0, integral - lag * value)


@allocating
def lag_response(u, decay):
    """f (N+1, n) at the hold breakpoints of a first-order lag from rest: f_(k+1) = u_k + (f_k - u_k) decay_k."""
    f = np.zeros((u.shape[0] + 1, u.shape[1]))
    for k in range(u.shape[0]):
        for j in range(u.shape[1]):
            f[k + 1, j] = u[k, j] + (f[k, j] - u[k, j]) * decay[k, 0]
    return f


def smooth(y: np.ndarray, samples: int) -> np.ndarray:
    """Savitzky-Golay (quadratic, `samples` odd) along the first axis: zero phase, polynomials kept."""
    return savgol_filter(y, samples, SMOOTHING_ORDER, axis=0, mode="interp") if samples > SMOOTHING_ORDER + 1 else y


@dataclass(frozen=True)
class Windows:
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


def state_integrals(t: np.ndarray, eta: np.ndarray, nu: np.ndarray, a: np.ndarray, b: np.ndarray,
                     rigid: np.ndarray, samples: int) -> dict[str, np.ndarray]:
    """The state-dependent fields of `Windows` for windows [t[a], t[b]] of one stretch, from the states smoothed
    over `samples` ticks."""
    eta, nu = smooth(eta, samples), smooth(nu, samples)
    units = [np.diag(np.eye(6)[i]) for i in range(6)]
    terms = np.concatenate([
        nu, np.abs(nu) * nu,
        np.stack([np.einsum("nij,nj->ni", coriolis(u, nu), nu) for u in units], axis=1).reshape(-1, 36),
        np.einsum("nij,nj->ni", coriolis(rigid, nu), nu),
        rotation(eta)[:, 2, :]], axis=1)
    cum = cumulative(t, terms)
    integral = cum[b] - cum[a]
    return dict(duration=t[b] - t[a], dnu=nu[b] - nu[a], nu=integral[:, :6], nu_abs=integral[:, 6:12],
                coriolis_unit=integral[:, 12:48].reshape(-1, 6, 6), coriolis_rigid=integral[:, 48:54],
                rho=integral[:, 54:57])


@dataclass(frozen=True)
class Piece:
    """An unbroken stretch of a run, and the windows it is cut into."""

    t: np.ndarray          # (N,) s, the states' times
    sent: np.ndarray       # (N,) s, when each command left (vehicle time)
    nominal: np.ndarray    # (N, 8) N, the bench thrust of each command
    reference: np.ndarray  # (N, 18)
    a: np.ndarray          # (W,) first tick of each window
    b: np.ndarray          # (W,) last tick
    samples: int           # span of the smoothing, ticks (odd; 1: none)


class Flights:
    """The runs cut into windows, as measured and as the reference asked; thrust integrals for any delay."""

    def __init__(self, runs: list[Run], prior: Vehicle, window: float, smoothing: float):
        t200 = thruster_curve(replace(prior, thrust_scale=np.ones(2), per_thruster_scale=np.ones_like(
            prior.per_thruster_scale)))
        self.lag = prior.thruster_time_constant
        rigid = prior.rigid_body_mass_matrix
        self.pieces: list[Piece] = []
        measured, asked = [], []
        for run in map(distinct, runs):
            nominal = bench_thrusts(run, t200)
            for piece in stretches(run):
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
                nu_d = body_velocity(eta_d, ref[:, 6:12])
                label = np.full(a.size, len(self.pieces))
                measured.append(state_integrals(t, run.eta[piece], run.nu[piece], a, b, rigid, samples)
                                | {"piece": label})
                asked.append(state_integrals(t, eta_d, nu_d, a, b, rigid, 1) | {"piece": label})
                self.pieces.append(Piece(t, sent, nominal[piece], ref, a, b, samples))
        if not measured:
            raise IdentificationError("the logs hold no stretch of flight longer than one window")
        if max(np.abs(p.nominal).max() for p in self.pieces) < STILL_THRUST:
            raise IdentificationError("the thrusters never pushed in these logs: nothing to fit "
                                      "(fly the shipped mission identify)")
        self.measured = {k: np.concatenate([m[k] for m in measured]) for k in measured[0]}
        self.asked = {k: np.concatenate([m[k] for m in asked]) for k in asked[0]}

    def _thrust(self, commands: list[np.ndarray], delay: float, smoothed: bool) -> dict[str, np.ndarray]:
        """thrust_pos and thrust_neg of `Windows` for per-stretch commands (N, 8)."""
        pos, neg = [], []
        for p, u in zip(self.pieces, commands):
            for side, part in ((pos, np.maximum(u, 0.0)), (neg, np.minimum(u, 0.0))):
                cum = smooth(lagged_integral(p.t, p.sent, part, delay, self.lag), p.samples if smoothed else 1)
                side.append(cum[p.b] - cum[p.a])
        return {"thrust_pos": np.concatenate(pos), "thrust_neg": np.concatenate(neg)}

    def measured_windows(self, delay: float) -> Windows:
        """The measured windows, the bench thrust delayed by `delay` s and smoothed as the states are (the same
        linear filter on every term keeps the balance exact)."""
        return Windows(**self.measured, **self._thrust([p.nominal for p in self.pieces], delay, True))

    def demand(self, vehicle: Vehicle) -> list[np.ndarray]:
        """Per stretch, the bench thrust (N, 8) `vehicle` would need to fly the reference exactly (Eq. 2.17 with
        e = 0: `tuning.feedforward`, allocated by the pseudo-inverse)."""
        allocate = np.linalg.pinv(allocation_matrix(vehicle.thruster_positions, vehicle.thruster_directions))
        commands = []
        for p in self.pieces:
            thrust = np.einsum("ij,nj->ni", allocate, feedforward(vehicle, p.reference))
            scale = np.where(thrust > 0, vehicle.thrust_scale[0], vehicle.thrust_scale[1]) * vehicle.per_thruster_scale
            commands.append(thrust / scale)
        return commands

    def reference_windows(self, delay: float, demand: list[np.ndarray]) -> Windows:
        """The reference's windows with a `demand`ed thrust: the instruments, free of sensor noise."""
        return Windows(**self.asked, **self._thrust(demand, delay, False))


def horizontal(vehicle: Vehicle) -> np.ndarray:
    """(n,) which thrusters push in the body's x-y plane (the group whose height and scale theta holds)."""
    return np.abs(vehicle.thruster_directions[:, 2]) < 0.1


class Balance:
    """Both sides of the integrated balance, and their Jacobian, for a parameter vector theta (the module
    docstring's layout) of a vehicle like `prior` (its mass, inertia, centre of gravity and thruster geometry)."""

    def __init__(self, prior: Vehicle):
        self.prior = prior
        self.rigid = prior.rigid_body_mass_matrix
        self.weight = prior.weight
        self.r_g = prior.center_of_gravity
        r, e = prior.thruster_positions, prior.thruster_directions
        vertical = np.abs(e[:, 2]) > 0.9
        self.horizontal = horizontal(prior)
        self.positions, self.masks = r, []
        for mask in (vertical[:, None] * [0, 1, 0], vertical[:, None] * [1, 0, 0],
                     self.horizontal[:, None] * [1, 1, 0]):
            self.masks.append(mask.astype(float))
        self.b0 = allocation_matrix(r, e)
        self.b_arm = []
        for mask in self.masks:
            arm = allocation_matrix(r * mask, e)
            arm[:3] = 0.0
            self.b_arm.append(arm)
        self.b_height = allocation_matrix(self.horizontal[:, None] * [0.0, 0.0, 1.0], e)   # per m of height
        self.b_height[:3] = 0.0
        moment, self.group0 = theta_of(prior)[27:29]
        self.height0 = float(moment / self.group0)
        self.b0 -= self.height0 * self.b_height
        self.base = prior.per_thruster_scale / np.where(self.horizontal, self.group0, 1.0)
        self.hold_height = False    # True: the horizontal thrusters stay at the prior's height whatever their scale
        self.dofs = np.ones(6)      # 1: the DOF's balance is fitted; 0: left out (its data cannot be trusted)

    def _matrix(self, arms: np.ndarray) -> np.ndarray:
        """The allocation matrix without the horizontal thrusters' roll and pitch moments (their height's)."""
        return self.b0 + sum((s - 1.0) * b for s, b in zip(arms, self.b_arm))

    def gain(self, theta: np.ndarray) -> np.ndarray:
        """(n,) each thruster's scale on the bench thrust (the vehicle's per_thruster_scale)."""
        return self.base * np.where(self.horizontal, theta[28], 1.0)

    def moment(self, theta: np.ndarray) -> float:
        """g h: theta's, or with the height held (`hold_height`), the prior's height times theta's g."""
        return theta[28] * self.height0 if self.hold_height else theta[27]

    def _thrust_side(self, theta: np.ndarray, thrust: np.ndarray) -> np.ndarray:
        """(W, 6) the wrench of bench thrusts (W, 8) times the thrust scales: k (per direction) already in."""
        return (np.einsum("wj,ij->wi", self.gain(theta) * thrust, self._matrix(theta[24:27]))
                + self.moment(theta) * np.einsum("wj,ij->wi", self.base * thrust, self.b_height))

    def sides(self, theta: np.ndarray, w: Windows) -> tuple[np.ndarray, np.ndarray]:
        """(model side, thrust side), each (W, 6), as mean force over each window (N, N m)."""
        A, Dl, Dq = theta[0:6], theta[6:12], theta[12:18]
        buoyancy, lever = theta[18], theta[19:22]
        lhs = (np.einsum("wj,ij->wi", w.dnu, self.rigid) + A * w.dnu + np.einsum("wpi,p->wi", w.coriolis_unit, A)
               + w.coriolis_rigid + Dl * w.nu + Dq * w.nu_abs)
        net = self.weight - buoyancy
        lhs[:, :3] -= net * w.rho
        lhs[:, 3:] -= np.cross(net * self.r_g - buoyancy * lever, w.rho)
        rhs = self._thrust_side(theta, theta[22] * w.thrust_pos + theta[23] * w.thrust_neg)
        per = self.dofs / w.duration[:, None]
        return lhs * per, rhs * per

    def jacobian(self, theta: np.ndarray, w: Windows) -> np.ndarray:
        """d(model side - thrust side)/d theta, (W, 6, 29): exact, the model being at most bilinear."""
        buoyancy, lever = theta[18], theta[19:22]
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
        jac[:, :, 22] = -self._thrust_side(theta, w.thrust_pos)
        jac[:, :, 23] = -self._thrust_side(theta, w.thrust_neg)
        bench = theta[22] * w.thrust_pos + theta[23] * w.thrust_neg
        thrust = self.gain(theta) * bench
        for s, b in enumerate(self.b_arm):
            jac[:, :, 24 + s] = -np.einsum("wj,ij->wi", thrust, b)
        height = -np.einsum("wj,ij->wi", self.base * bench, self.b_height)
        jac[:, :, 28] = -np.einsum("wj,ij->wi", self.base * self.horizontal * bench, self._matrix(theta[24:27]))
        if self.hold_height:
            jac[:, :, 28] += self.height0 * height
        else:
            jac[:, :, 27] = height
        return jac * self.dofs[None, :, None] / w.duration[:, None, None]

    def vehicle(self, theta: np.ndarray) -> Vehicle:
        """The prior with theta's values in (volume from B, r_b from the lever, thruster positions from the arms and
        the horizontal thrusters' height, per-thruster scales from the horizontal group's)."""
        p = self.prior
        arms = theta[24:27]
        positions = self.positions * (1.0 + sum((s - 1.0) * m for s, m in zip(arms, self.masks)))
        positions[self.horizontal, 2] += self.moment(theta) / theta[28] - self.height0
        return replace(
            p, added_mass=theta[0:6].copy(), linear_damping=theta[6:12].copy(), quadratic_damping=theta[12:18].copy(),
            volume=float(theta[18] / (p.water_density * p.gravity)),
            center_of_buoyancy=p.center_of_gravity + theta[19:22], thrust_scale=theta[22:24].copy(),
            thruster_positions=positions, per_thruster_scale=self.gain(theta))


def theta_of(vehicle: Vehicle) -> np.ndarray:
    """A vehicle's theta (29,): its moment arms at 1; its horizontal thrusters' scale g (their mean) and the roll
    and pitch arm of their thrust, g times their mean height."""
    lever = vehicle.center_of_buoyancy - vehicle.center_of_gravity
    group = horizontal(vehicle)
    height = float(vehicle.thruster_positions[group, 2].mean()) if group.any() else 0.0
    scale = float(vehicle.per_thruster_scale[group].mean()) if group.any() else 1.0
    return np.concatenate([vehicle.added_mass, vehicle.linear_damping, vehicle.quadratic_damping, [vehicle.buoyancy],
                           lever, vehicle.thrust_scale, np.ones(3), [scale * height, scale]])
