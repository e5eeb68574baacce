"""The controllers' one compiled interface (Numba, cached): a kind id, a flat parameter vector, a flat state vector.

`controller_step` dispatches one control tick to the law of `kind`; the runner calls it tick by tick
(`rov_mav.control.controller.Controller`) and the offline closed loop for a whole swarm
(`rov_mav.offline.loop_kernel.simulate_batch`), so every law has exactly one implementation. The laws, each in its
own module with its sources: `backstepping` (baseline, constant, fuzzy: the report's law), `pid`, `smc`, `ismc`.
"""

from __future__ import annotations

from rov_mav.control import backstepping, ismc, pid, smc
from rov_mav.model.kernel import inlined

KIND_BASELINE = backstepping.SCHEDULE_NONE
KIND_CONSTANT = backstepping.SCHEDULE_CONSTANT
KIND_FUZZY = backstepping.SCHEDULE_FUZZY
KIND_PID = 3
KIND_SMC = 4
KIND_ISMC = 5

# Every controller's state fits this vector (integrators, estimates); a run starts with it zeroed.
STATE_SIZE = max(backstepping.STATE_SIZE, pid.STATE_SIZE, smc.STATE_SIZE, ismc.STATE_SIZE)


@inlined
def controller_step(kind, m, params, table, table_scale, eta, trig, nu, ref, dt, state, tau, tau_hat, s, grad, gamma):
    """One control tick of controller `kind` for the measured eta, nu (6,) against ref (18,) = [eta_d, eta_dot_d,
    eta_ddot_d], with trig = attitude_trig(eta), the controller's model m (packed vehicle), parameters `params` and,
    for the fuzzy schedule, the rate table and its samples per unit of input (table_scale). Advances `state`
    (STATE_SIZE,) by dt; writes tau (the body wrench), tau_hat (the wrench the law holds against the disturbance),
    s (its sliding variable), grad and gamma (the adaptation's direction and rates), (6,) each: zeros where a law
    has no such quantity."""
    if kind <= KIND_FUZZY:
        backstepping.step(kind, m, params, table, table_scale, eta, trig, nu, ref, dt, state, tau, tau_hat, s, grad,
                          gamma)
        return
    for i in range(6):
        grad[i] = 0.0
        gamma[i] = 0.0
    if kind == KIND_PID:
        pid.step(params, eta, trig, nu, ref, dt, state, tau, tau_hat, s)
    elif kind == KIND_SMC:
        smc.step(m, params, eta, trig, nu, ref, tau, tau_hat, s)
    else:
        ismc.step(m, params, eta, trig, nu, ref, dt, state, tau, tau_hat, s)
