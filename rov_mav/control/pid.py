"""ArduSub-style cascade PID, compiled: position P -> velocity PID, angle P -> rate PID; no model.

Structure followed (ArduPilot, libraries/AC_AttitudeControl):
- AC_PosControl.cpp, update_xy_controller / update_z_controller: the position error times a P gain (`_p_pos_xy`,
  `_p_pos_z`) plus the desired (reference) velocity as feed-forward gives the velocity target; a velocity PID
  (`_pid_vel_xy`, on the NE vector, in the NED frame) turns the velocity error into the command.
- ArduSub (ArduSub/mode_guided.cpp with Sub::translate_wpnav_rp): the horizontal command becomes forward and lateral
  thrust through the heading alone (the NE command rotated by yaw into the body's forward/right axes); the depth
  command drives the vertical thrusters directly (body heave).
- AC_AttitudeControl.cpp, input_euler_angle_roll_pitch_yaw / attitude_controller_run_quat: the angle error times
  the angle P gain plus the reference's Euler rates (feed-forward), converted to body rates (euler_rate_to_ang_vel),
  is the rate target; rate_controller_run: a rate PID per body axis gives the torque. Roll and pitch are
  stabilised to the reference attitude, yaw follows the reference heading.
- AC_PID.cpp, update_all: derivative of the error low-pass filtered (FLTD), integrator of ki * error clamped to
  +-IMAX, derivative reset on the first call.

Unlike ArduSub (acceleration and lean-angle units scaled to throttle by motor gains) the PID output here is the body
wrench directly (N, N m), so the gains carry the vehicle's scale; the depth loop has the same P -> velocity PID
form as the horizontal one (ArduSub adds an acceleration PID stage). Parameter vector:
[kp_pos (6) | kp_vel (6) | ki_vel (6) | kd_vel (6) | i_max (6) | d_filter_hz (1)]: per channel x, y, z (NED) and
roll, pitch, yaw. State: integrators (6), last errors (6), filtered derivatives (6), started flag (1).
tau_hat (logged) is minus the integrators' wrench: what the I terms hold against disturbance and buoyancy.
"""

from __future__ import annotations

import math

from rov_mav.model.kernel import inlined, rotation, wrap_angle

PARAMETERS = (("kp_pos", 6), ("kp_vel", 6), ("ki_vel", 6), ("kd_vel", 6), ("i_max", 6), ("d_filter_hz", 1))
TUNED = ("kp_pos", "kp_vel", "ki_vel", "kd_vel")
BOUNDS = {"kp_pos": (0.1, 5.0),
          "kp_vel": ([5.0, 5.0, 5.0, 0.5, 0.5, 0.5], [300.0, 300.0, 300.0, 30.0, 30.0, 30.0]),
          "ki_vel": ([0.1, 0.1, 0.1, 0.01, 0.01, 0.01], [100.0, 100.0, 100.0, 10.0, 10.0, 10.0]),
          "kd_vel": ([0.01, 0.01, 0.01, 0.001, 0.001, 0.001], [30.0, 30.0, 30.0, 3.0, 3.0, 3.0])}
STATE_SIZE = 19


@inlined
def step(params, eta, trig, nu, ref, dt, state, tau, tau_hat, s):
    """One tick of the cascade: writes tau, tau_hat (6,), s = 0 (no sliding variable); updates state."""
    kp_pos, kp, ki, kd, i_max = params[0:6], params[6:12], params[12:18], params[18:24], params[24:30]
    integrator, last_error, derivative = state[0:6], state[6:12], state[12:18]
    started = state[18] != 0.0
    cphi, sphi, cth, sth, cpsi, spsi = trig
    R = rotation(cphi, sphi, cth, sth, cpsi, spsi)
    u, v, w = nu[0], nu[1], nu[2]
    velocity_ned = (R[0] * u + R[1] * v + R[2] * w, R[3] * u + R[4] * v + R[5] * w, R[6] * u + R[7] * v + R[8] * w)
    # outer loops: velocity (NED) and Euler-rate targets with the reference's feed-forward
    e0 = ref[6] + kp_pos[0] * (ref[0] - eta[0]) - velocity_ned[0]
    e1 = ref[7] + kp_pos[1] * (ref[1] - eta[1]) - velocity_ned[1]
    e2 = ref[8] + kp_pos[2] * (ref[2] - eta[2]) - velocity_ned[2]
    r_phi = ref[9] + kp_pos[3] * wrap_angle(ref[3] - eta[3])
    r_th = ref[10] + kp_pos[4] * wrap_angle(ref[4] - eta[4])
    r_psi = ref[11] + kp_pos[5] * wrap_angle(ref[5] - eta[5])
    # Euler rates -> body rates (T^-1), minus the measured rates
    e3 = r_phi - sth * r_psi - nu[3]
    e4 = cphi * r_th + cth * sphi * r_psi - nu[4]
    e5 = -sphi * r_th + cth * cphi * r_psi - nu[5]
    error = (e0, e1, e2, e3, e4, e5)
    cutoff = params[30]
    alpha = dt / (dt + 1.0 / (2.0 * math.pi * cutoff)) if cutoff > 0.0 else 1.0
    out = tau_hat   # scratch for the channel outputs; tau_hat is written after they are consumed
    for i in range(6):
        if started and dt > 0.0:
            derivative[i] += alpha * ((error[i] - last_error[i]) / dt - derivative[i])
        elif not started:
            derivative[i] = 0.0
        integrator[i] = min(max(integrator[i] + ki[i] * error[i] * dt, -i_max[i]), i_max[i])
        last_error[i] = error[i]
        out[i] = kp[i] * error[i] + integrator[i] + kd[i] * derivative[i]
        s[i] = 0.0
    state[18] = 1.0
    # NE command through the heading into forward/right; depth command on the body's heave; torques as they are
    tau[0] = cpsi * out[0] + spsi * out[1]
    tau[1] = -spsi * out[0] + cpsi * out[1]
    tau[2] = out[2]
    tau[3], tau[4], tau[5] = out[3], out[4], out[5]
    tau_hat[0] = -(cpsi * integrator[0] + spsi * integrator[1])
    tau_hat[1] = -(-spsi * integrator[0] + cpsi * integrator[1])
    for i in range(2, 6):
        tau_hat[i] = -integrator[i]
