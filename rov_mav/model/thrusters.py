"""Thrusters: the 6x8 allocation matrix, the PWM <-> thrust map, and wrench <-> thrust allocation.

One force law for every thruster the project flies (`ThrusterMap`): a table of force against PWM and voltage (the
T200's measured data, or a quadratic law sampled on a 1 us grid), times a scale per direction and thruster.
Used in both directions: the simulator bridge turns 8 PWMs into thrusts (`ThrusterMap.thrust`) and a body wrench
(`Allocator.wrench`); the controller turns a wrench into thrusts (`Allocator.thrusts`) and 8 PWMs (`ThrusterMap.pwm`).

Conventions: body frame FRD (x forward, y starboard, z down), SI units (N, N m, V, A), PWM in microseconds.
A wrench is [X, Y, Z, K, M, N] (force, then moment about the body origin). Thrust f_i > 0 means PWM > 1500 and
pushes the vehicle along the thruster's unit vector e_i; f_i < 0 (PWM < 1500) pushes along -e_i.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from rov_mav.model.vehicle import QuadraticCurve, Vehicle

T200_DATA_FILE = "t200_performance.csv"
NEUTRAL_PWM = 1500.0


def allocation_matrix(positions: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """The thrust-configuration matrix B, (6, n): column i = [e_i ; r_i x e_i], so that wrench = B @ thrusts.

    positions: (n, 3) thruster positions r_i in m; directions: (n, 3) unit vectors e_i (body frame FRD)."""
    r = np.asarray(positions, dtype=float)
    e = np.asarray(directions, dtype=float)
    if r.ndim != 2 or r.shape[1] != 3 or e.shape != r.shape:
        raise ValueError(f"positions and directions must both be (n, 3), got {r.shape} and {e.shape}")
    return np.vstack([e.T, np.cross(r, e).T])


# --------------------------------------------------------------------------------------------------------------
# Thruster map (T200 data or a quadratic law)


@dataclass(frozen=True)
class _Curve:
    """The table at one supply voltage, on its PWM grid, unscaled; built (and cached) by `ThrusterMap._build_curve`.

    force: (P,) N, monotone non-decreasing in PWM; current: (P,) A; dead_band: (low, high) PWM, force == 0 there.
    forward_thrust/forward_pwm: (L,) non-decreasing thrust from 0 at the upper edge up to 1900 us, and its PWMs;
    reverse_thrust/reverse_pwm: the same for reverse thrust magnitudes, from the lower edge down to 1100 us."""

    force: np.ndarray
    current: np.ndarray
    dead_band: tuple[float, float]
    forward_thrust: np.ndarray
    forward_pwm: np.ndarray
    reverse_thrust: np.ndarray
    reverse_pwm: np.ndarray


def _invert_branch(thrust: np.ndarray, branch_thrust: np.ndarray, branch_pwm: np.ndarray) -> np.ndarray:
    """PWM giving `thrust` (any shape, >= 0) on one side of the dead band, by linear interpolation.

    branch_thrust: (L,) non-decreasing thrust magnitudes from 0 at the dead band's edge outward, strictly positive
    after index 0; branch_pwm: (L,) the matching PWMs. A thrust on a flat run maps to the run's PWM nearest neutral;
    a thrust beyond the largest maps to where the largest is first reached."""
    x = np.minimum(np.maximum(thrust, 0.0), branch_thrust[-1])        # (np.clip costs more than the work here)
    j = np.minimum(np.maximum(np.searchsorted(branch_thrust, x, side="left"), 1), len(branch_thrust) - 1)
    t0, t1 = branch_thrust[j - 1], branch_thrust[j]   # t0 < x <= t1 for x > 0, so t1 > t0
    p0, p1 = branch_pwm[j - 1], branch_pwm[j]
    return p0 + (x - t0) / (t1 - t0) * (p1 - p0)


def _monotone(force: np.ndarray, pwm: np.ndarray) -> np.ndarray:
    """`force` (P,) made non-decreasing in PWM by a cumulative max of |force| outward from neutral on each side."""
    fixed = force.copy()
    up = pwm >= NEUTRAL_PWM
    down = ~up
    fixed[up] = np.maximum.accumulate(force[up])
    fixed[down] = -np.maximum.accumulate(-force[down][::-1])[::-1]
    return fixed


class ThrusterMap:
    """Thrust and current against PWM and supply voltage, from a table (`load_t200`: Blue Robotics' T200 data;
    `quadratic`: ArduPilot SITL's law), the thrust times `forward_scale` above neutral and `reverse_scale` below.

    The scales are numbers, or (n,) arrays for n thrusters that share the table's shape but not its size; with arrays,
    PWMs and thrusts are (..., n) and the maxima (n,).

    The T200 data are sheets at a few voltages (10..20 V), each on the same PWM grid (1100..1900 us). Between grid
    points and between sheets everything is linear interpolation; voltages outside the sheets are clamped to the nearest
    one and PWMs outside the grid to its ends.

    Monotonicity: the measured force is not strictly monotone in PWM everywhere (a few 0.03-0.13 N dips near full
    throttle and in one mid-range point at 10 V). Each sheet's force is therefore replaced, once, by the cumulative
    max of |force| outward from neutral on each side (it moves five of the 1206 points, by at most 0.134 N).
    `thrust` and `pwm` both use this corrected curve, so thrust(pwm(f)) == f over the whole achievable range; on
    the short flat runs the correction creates, `pwm` returns the run's PWM nearest neutral. A convex blend of two
    monotone sheets is monotone, so all this holds at every voltage.

    Dead band: the PWMs where the force is exactly 0 (about 1464-1536 us at 12 V, 1472-1528 us at 16 V). Between two
    sheets it is the PWMs that are dead in both. `pwm(0)` is exactly 1500; any non-zero thrust, however small, maps
    to a PWM at or just outside the dead band's edge, never inside it.
    """

    def __init__(self, voltages: np.ndarray, pwm: np.ndarray, force: np.ndarray, current: np.ndarray,
                 forward_scale: float | np.ndarray = 1.0, reverse_scale: float | np.ndarray = 1.0):
        """voltages: (V,) V, increasing; pwm: (P,) us, increasing, contains 1500; force: (V, P) N; current: (V, P) A;
        scales: > 0, numbers or (n,)."""
        self.forward_scale = _positive(forward_scale)
        self.reverse_scale = _positive(reverse_scale)
        self.voltages = np.asarray(voltages, dtype=float)
        self.pwm_grid = np.asarray(pwm, dtype=float)
        force = np.asarray(force, dtype=float)
        _check_sheets(self.voltages, self.pwm_grid, force)
        self.force_table = np.array([_monotone(f, self.pwm_grid) for f in force])   # (V, P) N, corrected
        self.current_table = np.asarray(current, dtype=float)                       # (V, P) A
        self._curve = functools.lru_cache(maxsize=64)(self._build_curve)

    @classmethod
    def from_csv(cls, path: str | Path) -> "ThrusterMap":
        """Read a CSV with columns voltage_v, pwm_us, current_a, force_n (others ignored)."""
        table = np.genfromtxt(path, delimiter=",", names=True)
        voltages = np.unique(table["voltage_v"])
        sheets = [table[table["voltage_v"] == v] for v in voltages]
        sheets = [s[np.argsort(s["pwm_us"])] for s in sheets]
        pwm = sheets[0]["pwm_us"]
        if any(not np.array_equal(s["pwm_us"], pwm) for s in sheets):
            raise ValueError(f"{path}: the voltage sheets do not share one PWM grid")
        return cls(
            voltages,
            pwm,
            np.array([s["force_n"] for s in sheets]),
            np.array([s["current_a"] for s in sheets]),
        )

    @classmethod
    def quadratic(cls, curve: QuadraticCurve) -> "ThrusterMap":
        """ArduPilot SITL's submarine thrusters (libraries/SITL/SIM_Submarine.cpp, Submarine::calculate_forces):
        k sign(o) o^2 with o = (pwm - 1500) / full_scale, nothing within the dead band, whatever the voltage; k per
        thruster and direction. The table samples the law at every whole microsecond (exact where a vehicle is
        sent PWMs; 0.0001 N of interpolation between), so a non-zero thrust below the first live microsecond's
        maps between the band's edge and it, and rounding with error diffusion averages to it."""
        half = curve.full_scale
        grid = np.unique(np.concatenate([np.arange(np.ceil(NEUTRAL_PWM - half), np.floor(NEUTRAL_PWM + half) + 1),
                                         [NEUTRAL_PWM - half, NEUTRAL_PWM + half]]))
        o = (grid - NEUTRAL_PWM) / half
        low, high = curve.dead_band
        force = np.where((grid < low) | (grid > high), np.sign(o) * o * o, 0.0)
        sheets = np.array([force, force])          # two equal sheets: the same law at every voltage
        return cls(np.array([0.0, 1.0]), grid, sheets, np.zeros_like(sheets), curve.max_forward, curve.max_reverse)

    # -- public map ------------------------------------------------------------------------------------------

    def thrust(self, pwm: np.ndarray | float, voltage: float) -> np.ndarray:
        """Thrust in N (negative = reverse) for PWM(s) in us of any shape, at a battery voltage in V."""
        pwm = np.asarray(pwm, dtype=float)
        force = np.interp(pwm, self.pwm_grid, self._curve(float(voltage)).force)
        return force * np.where(pwm > NEUTRAL_PWM, self.forward_scale, self.reverse_scale)

    def pwm(self, thrust: np.ndarray | float, voltage: float) -> np.ndarray:
        """PWM in us (float, within [1100, 1900]) giving thrust(s) in N of any shape, at a voltage in V.

        0 -> exactly 1500; beyond the achievable range -> the PWM of the largest thrust; see the class docstring."""
        t = np.asarray(thrust, dtype=float)
        if not np.all(np.isfinite(t)):
            raise ValueError("thrust must be finite")
        c = self._curve(float(voltage))
        forward = _invert_branch(t / self.forward_scale, c.forward_thrust, c.forward_pwm)
        reverse = _invert_branch(-t / self.reverse_scale, c.reverse_thrust, c.reverse_pwm)
        return np.where(t > 0, forward, np.where(t < 0, reverse, NEUTRAL_PWM))

    def current(self, pwm: np.ndarray | float, voltage: float) -> np.ndarray:
        """Current drawn in A at PWM(s) in us of any shape and a voltage in V (0 in the dead band)."""
        return np.interp(pwm, self.pwm_grid, self._curve(float(voltage)).current)

    def max_forward(self, voltage: float) -> float | np.ndarray:
        """Largest forward thrust in N (at the grid's top, 1900 us) at a voltage in V; (n,) with per-thruster scales."""
        return float(self._curve(float(voltage)).force[-1]) * self.forward_scale

    def max_reverse(self, voltage: float) -> float | np.ndarray:
        """Largest reverse thrust magnitude in N (positive; at the grid's bottom) at a voltage in V: ~78 % of forward
        for the T200."""
        return float(-self._curve(float(voltage)).force[0]) * self.reverse_scale

    def dead_band(self, voltage: float) -> tuple[float, float]:
        """(low, high) PWM in us: the outermost grid PWMs around 1500 where the thrust is exactly 0."""
        return self._curve(float(voltage)).dead_band

    def scaled(self, forward: float | np.ndarray, reverse: float | np.ndarray) -> "ThrusterMap":
        """The same thrusters with every forward thrust multiplied by `forward` and every reverse one by `reverse`
        (> 0, numbers or per thruster; current unchanged): thrusters that push less (or more) than the table."""
        return ThrusterMap(self.voltages, self.pwm_grid, self.force_table, self.current_table,
                           _positive(forward) * self.forward_scale, _positive(reverse) * self.reverse_scale)

    # -- construction ----------------------------------------------------------------------------------------

    def _blend(self, table: np.ndarray, voltage: float) -> np.ndarray:
        """Row of `table` (V, P) linearly interpolated at `voltage`, clamped to the sheets' range."""
        if not np.isfinite(voltage):
            raise ValueError(f"voltage must be finite, got {voltage}")
        v = float(np.clip(voltage, self.voltages[0], self.voltages[-1]))
        k = int(np.clip(np.searchsorted(self.voltages, v, side="right") - 1, 0, len(self.voltages) - 2))
        w = (v - self.voltages[k]) / (self.voltages[k + 1] - self.voltages[k])
        return (1.0 - w) * table[k] + w * table[k + 1]

    def _build_curve(self, voltage: float) -> _Curve:
        force = self._blend(self.force_table, voltage)
        zero = np.flatnonzero(force == 0.0)
        low, high = zero[0], zero[-1]
        return _Curve(
            force=force,
            current=self._blend(self.current_table, voltage),
            dead_band=(float(self.pwm_grid[low]), float(self.pwm_grid[high])),
            forward_thrust=force[high:],
            forward_pwm=self.pwm_grid[high:],
            reverse_thrust=-force[low::-1],
            reverse_pwm=self.pwm_grid[low::-1],
        )


def _positive(scale: float | np.ndarray) -> float | np.ndarray:
    """A thrust scale as a float, or a float array for one per thruster; ValueError unless all > 0 and finite."""
    array = np.asarray(scale, dtype=float)
    if not (np.all(array > 0) and np.all(np.isfinite(array))):
        raise ValueError(f"thrust scales must be positive, got {array}")
    return float(array) if array.ndim == 0 else array


def _check_sheets(voltages: np.ndarray, pwm: np.ndarray, force: np.ndarray) -> None:
    """Raise ValueError unless every sheet is reverse below, zero in one band around, and forward above 1500 us."""
    if len(voltages) < 2 or np.any(np.diff(voltages) <= 0):
        raise ValueError("T200 data: need at least two sheets at increasing voltages")
    if np.any(np.diff(pwm) <= 0) or NEUTRAL_PWM not in pwm:
        raise ValueError("T200 data: the PWM grid must be increasing and contain 1500 us")
    if force.shape != (len(voltages), len(pwm)):
        raise ValueError(f"T200 data: force must be {(len(voltages), len(pwm))}, got {force.shape}")
    for v, f in zip(voltages, force):
        zero = np.flatnonzero(f == 0.0)
        one_band = len(zero) > 0 and np.all(f[zero[0]: zero[-1] + 1] == 0.0)
        if not one_band or not pwm[zero[0]] <= NEUTRAL_PWM <= pwm[zero[-1]]:
            raise ValueError(f"T200 data at {v:g} V: the zero-force PWMs are not one band around 1500 us")
        if np.any(f[: zero[0]] >= 0) or np.any(f[zero[-1] + 1:] <= 0):
            raise ValueError(f"T200 data at {v:g} V: force has the wrong sign outside the dead band")


@functools.cache
def load_t200(path: str | Path | None = None) -> ThrusterMap:
    """The T200 model from `path`, or from the shipped Blue Robotics data (rov_mav/data/t200_performance.csv).

    Cached: each path is read once per process."""
    if path is None:
        path = Path(str(resources.files("rov_mav") / "data" / T200_DATA_FILE))
    return ThrusterMap.from_csv(path)


@functools.cache
def _scaled_t200(forward: float, reverse: float) -> ThrusterMap:
    return load_t200() if forward == reverse == 1.0 else load_t200().scaled(forward, reverse)


def thruster_curve(vehicle: Vehicle) -> ThrusterMap:
    """What the vehicle's thrusters push: its file's quadratic law or the shipped T200 data, scaled by its
    `thrust_scale` (forward, reverse) and, when they differ from 1, its `per_thruster_scale` (then the map takes
    and gives (..., 8) arrays)."""
    forward, reverse = (float(v) for v in vehicle.thrust_scale)
    each = np.asarray(vehicle.per_thruster_scale, dtype=float)
    if vehicle.thruster_curve is None:
        curve = _scaled_t200(forward, reverse)
        return curve if np.all(each == 1.0) else load_t200().scaled(forward * each, reverse * each)
    curve = ThrusterMap.quadratic(vehicle.thruster_curve)
    return curve.scaled(forward, reverse) if np.all(each == 1.0) else curve.scaled(forward * each, reverse * each)


def pwms_to_thrusts(pwms: np.ndarray, voltage: float, t200: ThrusterMap | None = None) -> np.ndarray:
    """Thrusts (..., n) in N of n thrusters at PWMs (..., n) in us and a voltage in V (default: shipped T200)."""
    return (t200 or load_t200()).thrust(pwms, voltage)


def thrusts_to_pwms(thrusts: np.ndarray, voltage: float, t200: ThrusterMap | None = None) -> np.ndarray:
    """PWMs (..., n) in us (float; round before sending) for thrusts (..., n) in N at a voltage in V."""
    return (t200 or load_t200()).pwm(thrusts, voltage)


# --------------------------------------------------------------------------------------------------------------
# Allocation


@dataclass(frozen=True)
class AllocationInfo:
    """How close an allocation came to the requested wrench. Shapes: (6,) / scalar, or (N, 6) / (N,) for a batch.

    wrench: achieved B f; residual: tau - B f (N, N m); residual_norm: ||tau - B f||_2 (unweighted);
    saturated: True where the least-squares (pseudo-inverse) thrusts broke a limit and the bounded solver ran."""

    wrench: np.ndarray
    residual: np.ndarray
    residual_norm: np.ndarray | float
    saturated: np.ndarray | bool


class Allocator:
    """Maps a body wrench to thruster thrusts within per-thruster limits, and thrusts back to a wrench.

    Strategy for `thrusts(tau)`:
    1. The pseudo-inverse (minimum-norm least-squares) solution f = B+ tau, precomputed; with B of full row rank it
       reproduces tau exactly. If it is within [f_min, f_max] it is the answer (a few microseconds).
    2. Otherwise bounded least squares (scipy's BVLS): the f in the box minimising ||W (B f - tau)||_2.
       Why not uniform scaling of tau: B (6x8) has a two-dimensional null space, so a wrench whose pseudo-inverse
       solution breaks a limit is often still achievable exactly (the solver shifts thrust along the null space),
       and when it is not, BVLS gives the nearest achievable wrench: its (weighted) residual is never larger than
       that of the scaled wrench s tau (which is also in the box), and it does not give up heave or attitude
       authority because surge saturated. The price: the achieved wrench need not be parallel to tau. `info`
       reports the achieved wrench and residual so the caller can see (and log) what was lost.
       W = diag(weights) sets which axes give way first; with the default (all ones) 1 N and 1 N m count the same,
       so forces (tens of N) dominate moments (a few N m); raise the roll/pitch weights to protect attitude.
    Rebuild the allocator (about 0.2 ms) when the limits change, e.g. with the battery voltage.
    """

    def __init__(self, matrix: np.ndarray, f_min: np.ndarray, f_max: np.ndarray, weights: np.ndarray | None = None):
        """matrix: B (6, n); f_min (n,) N, <= 0 (reverse limits); f_max (n,) N, >= 0; weights (6,) > 0 or None."""
        self.matrix = np.asarray(matrix, dtype=float)
        n = self.matrix.shape[1]
        self.f_min = np.broadcast_to(np.asarray(f_min, dtype=float), (n,)).copy()
        self.f_max = np.broadcast_to(np.asarray(f_max, dtype=float), (n,)).copy()
        if self.matrix.shape[0] != 6 or np.linalg.matrix_rank(self.matrix) < 6:
            raise ValueError(f"allocation matrix must be 6 x n of rank 6, got {self.matrix.shape}")
        if np.any(self.f_min > 0) or np.any(self.f_max < 0):
            raise ValueError("thrust limits must satisfy f_min <= 0 <= f_max")
        self.weights = np.ones(6) if weights is None else np.asarray(weights, dtype=float)
        if self.weights.shape != (6,) or np.any(self.weights <= 0):
            raise ValueError("weights must be 6 positive numbers")
        self.pinv = np.linalg.pinv(self.matrix)
        self._weighted_matrix = self.weights[:, None] * self.matrix

    @classmethod
    def for_vehicle(
        cls, vehicle: Vehicle, voltage: float, t200: ThrusterMap | None = None, weights: np.ndarray | None = None,
        max_thrust: float | None = None,
    ) -> "Allocator":
        """Allocator for `vehicle`'s thrusters, limited to their thrust range at `voltage` V (`t200`, default the
        vehicle's `thruster_curve`), and to `max_thrust` N either way when given."""
        curve = t200 or thruster_curve(vehicle)
        n = len(vehicle.thruster_positions)
        cap = np.inf if max_thrust is None else max_thrust
        return cls(
            allocation_matrix(vehicle.thruster_positions, vehicle.thruster_directions),
            np.broadcast_to(-np.minimum(curve.max_reverse(voltage), cap), (n,)),
            np.broadcast_to(np.minimum(curve.max_forward(voltage), cap), (n,)),
            weights,
        )

    def wrench(self, thrusts: np.ndarray) -> np.ndarray:
        """Body wrench (..., 6) in N, N m from thrusts (..., n) in N."""
        return np.asarray(thrusts, dtype=float) @ self.matrix.T

    def thrusts(self, tau: np.ndarray) -> tuple[np.ndarray, AllocationInfo]:
        """Thrusts (n,) in N for a wrench tau (6,), or (N, n) for a batch (N, 6); see the class docstring."""
        tau = np.asarray(tau, dtype=float)
        f = tau @ self.pinv.T
        outside = np.any((f < self.f_min) | (f > self.f_max), axis=-1)
        if tau.ndim == 1:
            outside = bool(outside)
            if outside:
                f = self._bounded(tau)
        else:
            for i in np.flatnonzero(outside):
                f[i] = self._bounded(tau[i])
        achieved = self.wrench(f)
        residual = tau - achieved
        norm = np.linalg.norm(residual, axis=-1)
        info = AllocationInfo(
            wrench=achieved,
            residual=residual,
            residual_norm=float(norm) if tau.ndim == 1 else norm,
            saturated=outside,
        )
        return f, info

    def authority(self) -> np.ndarray:
        """(6,) the largest force (N) or moment (N m) along each axis alone, either way (the smaller of the two),
        that thrusts within their limits give with nothing on the other five axes: a linear program per axis and
        direction (SciPy's HiGHS)."""
        from scipy.optimize import linprog

        out = np.zeros(6)
        for axis in range(6):
            others = np.delete(self.matrix, axis, axis=0)
            reach = []
            for sign in (1.0, -1.0):
                result = linprog(-sign * self.matrix[axis], A_eq=others, b_eq=np.zeros(5),
                                 bounds=list(zip(self.f_min, self.f_max)), method="highs")
                reach.append(sign * float(self.matrix[axis] @ result.x) if result.success else 0.0)
            out[axis] = min(reach)
        return out

    def _bounded(self, tau: np.ndarray) -> np.ndarray:
        """Thrusts (n,) in [f_min, f_max] minimising ||W (B f - tau)||_2 for one wrench tau (6,). (SciPy's optimizers
        load here, on the first saturated wrench, not with the model: the bridge and `analyze` never need them.)"""
        from scipy.optimize import lsq_linear

        result = lsq_linear(self._weighted_matrix, self.weights * tau, bounds=(self.f_min, self.f_max), method="bvls")
        return np.clip(result.x, self.f_min, self.f_max)


def allocate(
    matrix: np.ndarray, tau: np.ndarray, f_min: np.ndarray, f_max: np.ndarray
) -> tuple[np.ndarray, AllocationInfo]:
    """One-off allocation: `Allocator(matrix, f_min, f_max).thrusts(tau)`. Build an Allocator to call it in a loop."""
    return Allocator(matrix, f_min, f_max).thrusts(tau)
