"""The compiled offline closed loop (Numba, cached): a batch of vehicles, each flown by a controller through the plant,
with the tuning cost (Eq. 2.32 and its tracking form) and the divergence and saturation cut-offs.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from rov_mav.control.law_kernel import STATE_SIZE, controller_step
from rov_mav.model.kernel import (
    E_FAULT_AT,
    E_FAULT_MAP,
    E_FAULT_PUSH,
    E_NOISE,
    E_PREDICT,
    E_SAMPLE_DELAY,
    E_SAMPLE_PERIOD,
    FAST,
    compiled,
    compiled_loop,
    inlined,
    observe_disturbance,
    predict,
    rk4_step,
    trig_near,
    wrap_angle,
)
from rov_mav.offline.noise import normal

# Limits beyond which a simulated vehicle counts as diverged (Assumption 1 and sanity bounds).
MAX_TILT = 1.4          # rad, |phi|, |theta| (the Euler kinematics are singular at pi/2)
MAX_SPEED = 20.0        # m/s or rad/s, any component of nu
DIVERGED_COST = 1.0e12


def printed_cost(ref: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """simulate_batch's (cost_weights, tau_ff, tau_max, tau_limit) for Eq. 2.32 as printed: Q = R = I, no
    saturation (neither cut-off nor clipping)."""
    return (np.array([np.ones(6), np.zeros(6), np.ones(6)]), np.zeros((ref.shape[0], 6)), np.full(6, np.inf),
            np.full(6, np.inf))


@inlined
def _diverged(x):
    total = 0.0
    for i in range(12):
        total += x[i]
    if not math.isfinite(total):   # a NaN or an infinity anywhere in x
        return True
    if abs(x[3]) > MAX_TILT or abs(x[4]) > MAX_TILT:
        return True
    for i in range(6, 12):
        if abs(x[i]) > MAX_SPEED:
            return True
    return False


@inlined
def _saturated(tau, tau_max):
    """True when a commanded |tau_i| exceeds tau_max_i: the thrusters cannot deliver it."""
    for i in range(6):
        if abs(tau[i]) > tau_max[i]:
            return True
    return False


@inlined
def _measure(x, noise, nav_error, k, out, rng):
    """The state as the sensors give it at tick k: out (12,) = x plus white noise (position, attitude, velocity, rate
    std) plus the navigation's error at k (nav_error (M, 6): position, body velocity; none past its end, M = 0 for
    none); returns the noise generator's next state."""
    for i in range(6):
        pose_sigma = noise[0] if i < 3 else noise[1]
        rate_sigma = noise[2] if i < 3 else noise[3]
        out[i] = x[i]
        out[6 + i] = x[6 + i]
        if pose_sigma > 0.0 or rate_sigma > 0.0:
            rng, n1 = normal(rng)
            rng, n2 = normal(rng)
            out[i] += n1 * pose_sigma
            out[6 + i] += n2 * rate_sigma
    if k < nav_error.shape[0]:
        for i in range(3):
            out[i] += nav_error[k, i]
            out[6 + i] += nav_error[k, 3 + i]
    return rng


@inlined
def _faulted(env, tau, scratch):
    """tau (6,) in place -> what failed thrusters give of it: F tau + push (`kernel.E_FAULT_MAP`); scratch (6,)."""
    for i in range(6):
        total = env[E_FAULT_PUSH + i]
        for j in range(6):
            total += env[E_FAULT_MAP + 6 * i + j] * tau[j]
        scratch[i] = total
    for i in range(6):
        tau[i] = scratch[i]


@inlined
def _running_cost(weights, s, x, ref, tau, tau_ff):
    """s^T Q s + e^T Q_e e + (tau - tau_ff)^T R (tau - tau_ff) at one tick (Eq. 2.32 and its tracking form)."""
    total = 0.0
    for i in range(6):
        u = tau[i] - tau_ff[i]
        total += weights[0, i] * s[i] * s[i] + weights[2, i] * u * u
        if weights[1, i] != 0.0:
            e = x[i] - ref[i]
            if i >= 3:
                e = wrap_angle(e)
            total += weights[1, i] * e * e
    return total


# The prediction called, not inlined, from the loop that predicts (and the law inlined there once, on the held or
# the predicted state): inlined, its RK4s and the law's second copy made the offline loop's first compilation, which
# every machine meets once (a first `rov-mav simulate`), 54 s instead of 40, for 3 % of a predicting tick.
@compiled
def _predict(m, x, trig, ring, newest, slot, horizon, d_hat, out, ws):
    """`kernel.predict`, compiled once."""
    return predict(m, x, trig, ring, newest, slot, horizon, d_hat, out, ws)


@compiled
def _observe(m, x_prev, trig_prev, ring, newest, slot, interval, x_new, d_hat, ws):
    """`kernel.observe_disturbance`, compiled once."""
    observe_disturbance(m, x_prev, trig_prev, ring, newest, slot, interval, x_new, d_hat, ws)


@compiled_loop
def _fly(plant, env, ctrl, params, kind, table, table_scale, ref, dt, substeps, x, seed, nav_error, cost_weights, tau_ff,
         tau_max, tau_limit, eta_log, nu_log, tau_log, tau_hat_log, s_log, gamma_log, measured, commanded, state, ws,
         predicting):
    """One run of simulate_batch from the state x (12,), advanced in place, its sensor noise seeded by seed and its
    navigation's error nav_error (M, 6) added to what it measures (`_measure`); the logs
    (N+1, 6) or (0, 6) are this run's. measured: (late + 1, 12) ring of the last late + 1 ticks' measurements (the
    telemetry delay; only the ticks telemetry delivers are measured); commanded: (R, 6) ring of the wrenches applied
    since, R > the oldest measurement's age in ticks (for the prediction); state: the controller's, zeroed; ws: zeroed
    workspace (254,); predicting: True when the law acts on the held measurement carried forward to its tick
    (`kernel.predict`), None when it acts on it as it is (a type of its own: Numba compiles that loop without the
    prediction's code, which, inlined and never run, made a tick take 1.8 times as long). Returns (cost, steps
    done)."""
    n_steps = ref.shape[0] - 1
    record = eta_log.shape[0] > 0
    h = dt / substeps
    every = max(1, int(round(env[E_SAMPLE_PERIOD] / dt)))
    late = measured.shape[0] - 1
    ws_plant = ws[0:80]
    eta_m = ws[80:86]
    nu_m = ws[86:92]
    tau_hat = ws[92:98]
    tau = ws[98:104]
    applied = ws[104:110]
    s = ws[110:116]
    grad = ws[116:122]
    gamma = ws[122:128]
    trig_m = ws[128:134]   # attitude_trig(eta_m), computed when a sample arrives
    x_m = ws[134:146]      # the measurement held, as a state
    x_p = ws[146:158]      # ... predicted to this tick
    x_prev = ws[158:170]   # the measurement held before
    d_hat = ws[170:176]    # the prediction's disturbance estimate
    ws_predict = ws[176:248]
    faulted = ws[248:254]  # scratch of the thrusters' faults
    eta_p = x_p[0:6]
    nu_p = x_p[6:12]
    held_at = 0       # the tick the held measurement was taken at
    newest = commanded.shape[0] - 1   # commanded[newest]: the wrench applied over the last tick
    noise = env[E_NOISE:E_NOISE + 4]
    total = 0.0
    rng = np.uint64(seed)
    slot = 0          # k % (late + 1): this tick's place in the ring
    for k in range(n_steps + 1):
        if every == 1 or k % every == 0:   # a measurement telemetry will deliver (late ticks from now)
            rng = _measure(x, noise, nav_error, k, measured[slot], rng)
        slot = slot + 1 if slot < late else 0   # the oldest measurement, k - late, is in the next place
        sampled = k - late
        if k == 0 or (sampled >= 0 and (every == 1 or sampled % every == 0)):
            held = measured[slot if sampled >= 0 else 0]
            trig = (trig_m[0], trig_m[1], trig_m[2], trig_m[3], trig_m[4], trig_m[5])
            for i in range(12):
                x_prev[i] = x_m[i]
                x_m[i] = held[i]
            for i in range(6):
                eta_m[i] = held[i]
                nu_m[i] = held[6 + i]
            if predicting is not None and sampled > held_at:   # what the model missed since the last measurement
                _observe(ctrl, x_prev, trig, commanded, newest - late, dt, (sampled - held_at) * dt, x_m, d_hat,
                         ws_predict)
            held_at = max(sampled, 0)
            trig_m[0], trig_m[1], trig_m[2], trig_m[3], trig_m[4], trig_m[5] = trig_near(eta_m, x, ws_plant)
        trig = (trig_m[0], trig_m[1], trig_m[2], trig_m[3], trig_m[4], trig_m[5])
        eta_c, nu_c = eta_m, nu_m   # what the law acts on: the held measurement, or it predicted to this tick
        if predicting is not None and k > held_at:
            trig = _predict(ctrl, x_m, trig, commanded, newest, dt, (k - held_at) * dt, d_hat, x_p,
                            ws_predict[0:60])
            eta_c, nu_c = eta_p, nu_p
        controller_step(kind, ctrl, params, table, table_scale, eta_c, trig, nu_c, ref[k], dt, state, tau, tau_hat, s,
                        grad, gamma)
        if record:
            for i in range(6):
                eta_log[k, i] = x[i]
                nu_log[k, i] = x[6 + i]
                tau_log[k, i] = tau[i]
                tau_hat_log[k, i] = tau_hat[i]
                s_log[k, i] = s[i]
                gamma_log[k, i] = gamma[i]
        if k == n_steps:
            break
        if _saturated(tau, tau_max):
            return DIVERGED_COST, k
        total += _running_cost(cost_weights, s, x, ref[k], tau, tau_ff[k]) * dt
        newest = newest + 1 if newest < commanded.shape[0] - 1 else 0
        for i in range(6):
            applied[i] = min(max(tau[i], -tau_limit[i]), tau_limit[i])
            commanded[newest, i] = applied[i]
        if k * dt >= env[E_FAULT_AT]:
            _faulted(env, applied, faulted)
        for j in range(substeps):
            rk4_step(plant, env, x, applied, k * dt + j * h, h, ws_plant)
        if _diverged(x):
            return DIVERGED_COST, k
    return total, n_steps


@njit(cache=True, fastmath=FAST, error_model="numpy", nogil=True)
def simulate_batch(plant, env, ctrl, params, kind, table, table_scale, ref, dt, substeps, x0, seeds, nav_errors,
                   nav_index, cost_weights, tau_ff, tau_max, tau_limit, eta_log, nu_log, tau_log, tau_hat_log, s_log,
                   gamma_log, cost, steps_done):
    """Closed-loop runs of a batch of vehicles: controller at 1/dt, plant by RK4 at dt/substeps.

    plant (B, 92), env (B, 22): each run's true vehicle and environment; ctrl (92,): the controller's model;
    params (B, P): each run's controller parameter vector for controller `kind` (`law_kernel.controller_step`,
    with the fuzzy rate table and its table_scale); ref (N+1, 18): reference at t_k = k dt; x0 (12,); seeds (B,) for
    sensor noise; nav_errors (E, M, 6): navigation errors (position, body velocity at each tick: the built-in
    vehicle's estimate along the mission, `sim_bridge.navigation.estimate_errors`; M = 0 for none), run b's nav_errors[nav_index[
    b]]. The controller sees the measured state (true state plus the environment's sensor noise, drawn for
    each tick whose measurement telemetry delivers) as telemetry delivers it: sampled every E_SAMPLE_PERIOD s and E_SAMPLE_DELAY s late, held between samples (before
    the first sample arrives, the measurement at t = 0); period and delay 0 give every tick's measurement at once.
    Where E_PREDICT is set, the controller acts on the held measurement carried forward to its tick through its own
    model and the wrenches applied since (`kernel.predict`), as `rov-mav run` predicts its late telemetry. From
    E_FAULT_AT s on, the plant gets what failed thrusters give of the applied wrench (the controller, not knowing,
    predicts with what it asked).
    cost (B,) receives Eq. 2.32 extended, J = sum (s^T Q s + e^T Q_e e + u^T R u) dt with u = tau - tau_ff[k],
    e the true tracking error and cost_weights (3, 6) = diagonals of [Q; Q_e; R] (the printed Eq. 2.32:
    Q = R = I, Q_e = 0, tau_ff = 0). A run stops early with DIVERGED_COST when it diverges or when a commanded
    |tau_i| exceeds tau_max (6,) (thruster saturation as failure, for tuning); otherwise the plant receives the
    commanded wrench clipped to +-tau_limit (6,) per axis (saturation as the vehicle meets it; inf: none).
    steps_done (B,) receives the index of the last tick logged (N for a run that completed; a run that ends early
    stops at the last state before it failed). The *_log arrays are (B, N+1, 6) to record the true state and the
    commanded (unclipped) wrench, or (B, 0, 6) to skip recording.
    Releases the GIL: callers may run disjoint slices of a batch in parallel threads."""
    for b in range(params.shape[0]):
        late = max(0, int(round(env[b, E_SAMPLE_DELAY] / dt)))
        every = max(1, int(round(env[b, E_SAMPLE_PERIOD] / dt)))
        x, measured, commanded = x0.copy(), np.zeros((late + 1, 12)), np.zeros((late + every + 1, 6))
        state, ws = np.zeros(STATE_SIZE), np.zeros(254)
        if env[b, E_PREDICT] != 0.0 and (late > 0 or every > 1):   # a late or held measurement to carry forward
            cost[b], steps_done[b] = _fly(plant[b], env[b], ctrl, params[b], kind, table, table_scale, ref, dt,
                                          substeps, x, seeds[b], nav_errors[nav_index[b]], cost_weights, tau_ff,
                                          tau_max, tau_limit, eta_log[b], nu_log[b], tau_log[b], tau_hat_log[b],
                                          s_log[b], gamma_log[b], measured, commanded, state, ws, True)
        else:
            cost[b], steps_done[b] = _fly(plant[b], env[b], ctrl, params[b], kind, table, table_scale, ref, dt,
                                          substeps, x, seeds[b], nav_errors[nav_index[b]], cost_weights, tau_ff,
                                          tau_max, tau_limit, eta_log[b], nu_log[b], tau_log[b], tau_hat_log[b],
                                          s_log[b], gamma_log[b], measured, commanded, state, ws, None)
