"""The runner's actuation: wrench -> 8 thrusts -> 8 PWMs, at the battery voltage, within the thrust cap.

One allocator and one thruster map for the project (`rov_mav.model.thrusters`: the vehicle file's T200 data or
quadratic law, scaled by its `thrust_scale` and `per_thruster_scale`); this only keeps their limits current: each
thruster's range is its map's at the measured battery voltage, capped at `max_thrust` N both ways. The cap is also held
in the PWM domain (per
thruster), at the highest voltage seen: the battery's voltage sags and recovers faster than the vehicle reports it,
and a PWM computed at a sagged voltage pushes harder once the voltage recovers.
A thruster found not to do what it is told (`rov_mav.flight.thrusters.thruster_health`) is allocated with its
effectiveness g:
the allocation solves for the thrust it gives (its column of B unchanged, its range g times its own), and it is told
that thrust divided by g; a dead or stuck one (g = 0) has its column zeroed, is told nothing and is left out of the
pretension.
Passthrough bypasses ArduSub's MOT_n_DIRECTION, so reversed thrusters (direction -1) get the PWM mirrored about 1500.

PWMs go out in whole microseconds, and no PWM gives a thrust inside a dead band's edge step (ArduPilot SITL's
thrusters jump from 0 to 0.22 N at 1526 us). With `diffuse` (the default), each tick carries to the next what its
PWM could not give (thrust asked minus the thrust the sent PWM gives: error diffusion), so the thrust averaged over
ticks is the thrust asked. With `pretension` (the default) a pattern of thrusts with no net wrench is added first
(`rov_mav.model.pretension`), so that every thruster pushes at least its dead band's edge thrust (the thrust 5 us
beyond the band) either way: small moments and the heave trim are then made where thrust is a smooth function of
PWM, not by thrusters switching on and off at the band's edge. Measured on ArduSub SITL, that switching excited the
vehicle's pitch: 0.03-0.07 deg RMS without pretension, 0.005 deg with it.
"""

from __future__ import annotations

import numpy as np

from rov_mav.model.pretension import Pretension, sparse_null_vectors
from rov_mav.model.thrusters import (
    AllocationInfo,
    Allocator,
    thruster_curve,
    thrusts_to_pwms,
)

VOLTAGE_STEP = 0.1        # V: rebuild the allocator when the battery moved this much
DEFAULT_VOLTAGE = 16.0    # V: until the vehicle reports one (a charged 4S pack under load)
NEUTRAL = 1500            # us
PWM_TOLERANCE = 2         # us: a reported output this far beyond the PWM cap counts as crossing it
MAX_CARRY = 1.0           # N: the most thrust carried to the next tick (a rounding or dead-band step is far less)
EDGE_MARGIN = 5.0         # us beyond a dead band's edge: the smallest thrust pretension keeps each thruster at
# Saturated allocation gives way on translation before roll and pitch: 1 N m of roll or pitch not given counts as
# 100 N of force. A vehicle that keeps its attitude keeps its thrusters pointing where the allocation assumes; with
# all axes weighted alike, a saturated surge demand on SITL pitched the vehicle 46 deg within a second.
ALLOCATION_WEIGHTS = np.array([1.0, 1.0, 1.0, 100.0, 100.0, 1.0])
PROBE_THRUST = 1.0        # N: amplitude of the null-space probe (no net wrench while every thruster works), along the
                          # patterns of the horizontal thrusters only (a slight mismatch cannot heave, roll or pitch)
PROBE_PERIOD = 2.0        # vehicle s


class Actuation:
    """`command(tau)` -> (thrusts (8,) N, PWMs (8,) us as sent, AllocationInfo)."""

    def __init__(self, vehicle, max_thrust: float | None = None, voltage: float = DEFAULT_VOLTAGE,
                 diffuse: bool = True, pretension: bool = True, probe: bool = False):
        self.vehicle = vehicle
        self.diffuse = diffuse
        self.pretension: Pretension | None = None
        self._use_pretension = pretension
        self.carry = np.zeros(len(vehicle.thruster_positions))   # N owed to the next tick
        self.max_thrust = max_thrust
        self.t200 = thruster_curve(vehicle)
        self.directions = np.ones(len(vehicle.thruster_positions))
        self.voltage = float("nan")
        self.peak_voltage = 0.0
        self.pwm_range = (np.full(len(vehicle.thruster_positions), 1100.0),
                          np.full(len(vehicle.thruster_positions), 1900.0))
        self.allocator: Allocator | None = None
        self.gains = np.ones(len(vehicle.thruster_positions))    # each thruster's effectiveness (1: healthy)
        self.delivered = np.zeros(len(vehicle.thruster_positions))   # N the last PWMs sent ask for (clipped, whole us)
        self.probe = probe
        self.set_voltage(voltage)

    def set_voltage(self, voltage: float) -> None:
        if voltage > self.peak_voltage:
            self.peak_voltage = float(voltage)
            if self.max_thrust is not None:
                n = len(self.vehicle.thruster_positions)
                self.pwm_range = (np.floor(self.t200.pwm(np.full(n, -self.max_thrust), self.peak_voltage)),
                                  np.ceil(self.t200.pwm(np.full(n, self.max_thrust), self.peak_voltage)))
        if abs(voltage - self.voltage) < VOLTAGE_STEP:
            return
        self.voltage = float(voltage)
        self._allocate()

    def set_gain(self, thruster: int, gain: float) -> None:
        """Thruster `thruster` (0-based) gives `gain` of the thrust it is told (0: nothing, -1: reversed): allocate
        around it from now on."""
        self.gains[thruster] = gain
        self._allocate()
        self.carry[thruster] = 0.0

    def _allocate(self) -> None:
        healthy = Allocator.for_vehicle(self.vehicle, self.voltage, self.t200, weights=ALLOCATION_WEIGHTS,
                                        max_thrust=self.max_thrust)
        g = self.gains
        self._active = np.flatnonzero(g != 0.0)
        heave = np.abs(healthy.matrix[2, self._active]) > 1e-9   # vertical thrusters: the probe leaves them alone
        self._probe = [v for v in sparse_null_vectors(healthy.matrix[:, self._active])
                       if not np.any(heave & (np.abs(v) > 1e-9))]
        kept = np.where(g != 0.0, g, 1.0)           # a thruster left out keeps its range, its column zeroed
        self.allocator = Allocator(healthy.matrix * (g != 0.0), np.minimum(kept * healthy.f_min, kept * healthy.f_max),
                                   np.maximum(kept * healthy.f_min, kept * healthy.f_max), ALLOCATION_WEIGHTS)
        if self._use_pretension:
            self.pretension = Pretension(healthy.matrix[:, self._active],
                                         np.abs(g[self._active]) * self._edge_thrust(self.voltage)[self._active])

    def _edge_thrust(self, voltage: float) -> np.ndarray:
        """(n,) N: each thruster's thrust EDGE_MARGIN us beyond its dead band, the smaller of the two directions."""
        n = len(self.vehicle.thruster_positions)
        low, high = self.t200.dead_band(voltage)
        forward = self.t200.thrust(np.full(n, high + EDGE_MARGIN), voltage)
        reverse = -self.t200.thrust(np.full(n, low - EDGE_MARGIN), voltage)
        return np.minimum(forward, reverse)

    def set_directions(self, directions: np.ndarray) -> None:
        """MOT_1..8_DIRECTION of the vehicle (+1 or -1 each)."""
        self.directions = np.where(np.asarray(directions, dtype=float) < 0, -1.0, 1.0)

    def command(self, tau: np.ndarray, t: float | None = None) -> tuple[np.ndarray, np.ndarray, AllocationInfo]:
        """(thrusts (8,) N each thruster is told, PWMs (8,) us as sent, the allocation's info); t: vehicle s, for
        the probe."""
        given, info = self.allocator.thrusts(tau)
        if self.probe and t is not None and not info.saturated:
            phase = 2.0 * np.pi * t / PROBE_PERIOD
            for j, vector in enumerate(self._probe):
                given[self._active] += PROBE_THRUST * np.sin(phase + j * np.pi / 2) * vector
        if self.pretension is not None and not info.saturated:
            given[self._active] = self.pretension.apply(given[self._active])
        thrusts = np.zeros_like(given)
        thrusts[self._active] = given[self._active] / self.gains[self._active]
        asked = thrusts + self.carry if self.diffuse else thrusts
        low, high = self.pwm_range
        pwm = np.minimum(np.maximum(np.round(thrusts_to_pwms(asked, self.voltage, self.t200)), low), high)
        self.delivered = self.t200.thrust(pwm, self.voltage)     # what the PWMs sent ask of each thruster, N
        if self.diffuse:
            owed = asked - self.delivered
            self.carry = np.where((pwm <= low) | (pwm >= high), 0.0, np.minimum(np.maximum(owed, -MAX_CARRY),
                                                                                MAX_CARRY))
        return thrusts, NEUTRAL + self.directions * (pwm - NEUTRAL), info

    def reset(self) -> None:
        """Forget the carried thrust and the pretension (after neutral was sent instead of a command)."""
        self.carry[:] = 0.0
        if self.pretension is not None:
            self.pretension.reset()

    def describe_range(self) -> str:
        """The PWM range the cap allows: "1141-1859 us", or one range per thruster when they differ."""
        ranges = [f"{lo:.0f}-{hi:.0f}" for lo, hi in zip(*self.pwm_range)]
        return f"{ranges[0]} us" if len(set(ranges)) == 1 else f"({', '.join(ranges)}) us"

    def beyond_cap(self, outputs: np.ndarray) -> np.ndarray:
        """Which of the vehicle's reported outputs (8,) us lie beyond the PWM range the thrust cap allows."""
        pwm = NEUTRAL + self.directions * (np.asarray(outputs, dtype=float) - NEUTRAL)
        low, high = self.pwm_range
        return (pwm < low - PWM_TOLERANCE) | (pwm > high + PWM_TOLERANCE)
