"""The autopilot's navigation estimate (EKF3 aided by a DVL for horizontal position and velocity, a Bar30 for depth)
under the vehicle's faults: what the controllers fly on, and what EKF_STATUS_REPORT and LOCAL_POSITION_NED show.

Healthy, the estimate is the measured state and the EKF aids absolutely: flags 831 (attitude, horizontal and
vertical velocity, relative and absolute horizontal position, vertical position, both predicted horizontal
positions; NavEKF3_core `updateFilterStatus` / `send_status_report`), every variance HEALTHY_VARIANCE (chosen).
The position source lost (`navigation_ok` false; the DVL gives both horizontal position and velocity):
- the velocity and horizontal-position variances grow by VARIANCE_GROWTH a second from HEALTHY_VARIANCE (chosen:
  with no horizontal measurement the filter's uncertainty grows; FS_EKF_THRESH's default 0.8 is crossed after 7.5 s)
  and stop at VARIANCE_MAX; the estimate dead-reckons on an ideal IMU (follows the truth: chosen, optimistic);
- after POS_TIMEOUT the position and velocity aiding time out (EKF3 `setAidingMode`, posRetryTimeNoVel_ms): the
  horizontal velocity and position flags drop (37), so `Sub::position_ok` is false;
- after AID_NONE_AFTER the attitude aiding is lost too (tiltDriftTimeMax_ms): the EKF goes to AID_NONE, constant
  position mode (165), WARNING "EKF3 IMU0 stopped aiding"; the horizontal estimate is held where it was and its
  horizontal velocity is 0, and LOCAL_POSITION_NED is no longer sent (`getPosNE` false in AID_NONE); GLOBAL_POSITION_INT
  still is, stale (`send_global_position_int` ignores the failure).
- When it returns: aiding again at once (healthy flags and variances, the estimate back on the measured state);
  coming out of AID_NONE, INFO "EKF3 IMU0 is using external nav data" and "EKF3 IMU0 initial pos NED = x,y,z (m)".
A fresh EKF without the source (booted while it is lost) starts in AID_NONE, held where the vehicle was, silent.
The 7 s and 15 s are EKF3's defaults as read by the fact sheet (not checked against 4.7's code); one EKF core (IMU0)
is reported, though a board with two IMUs runs and reports two.
The depth sensor failed (`depth_healthy` false): the estimate's depth is held at its last value (chosen; the EKF would
dead-reckon its height on the IMU) and its vertical velocity follows the measured state; the flags do not change.
"""

from __future__ import annotations

import numpy as np

from rov_mav.model.dynamics import rotation

ATTITUDE, VEL_HORIZ, VEL_VERT, POS_HORIZ_REL, POS_HORIZ_ABS, POS_VERT_ABS = 1, 2, 4, 8, 16, 32
CONST_POS_MODE, PRED_POS_HORIZ_REL, PRED_POS_HORIZ_ABS = 128, 256, 512
HEALTHY_FLAGS = (ATTITUDE | VEL_HORIZ | VEL_VERT | POS_HORIZ_REL | POS_HORIZ_ABS | POS_VERT_ABS | PRED_POS_HORIZ_REL
                 | PRED_POS_HORIZ_ABS)
TIMED_OUT_FLAGS = ATTITUDE | VEL_VERT | POS_VERT_ABS
CONST_POS_FLAGS = TIMED_OUT_FLAGS | CONST_POS_MODE
POS_TIMEOUT = 7.0              # s without horizontal aiding until the position times out
AID_NONE_AFTER = 15.0          # s until AID_NONE (constant position mode)
HEALTHY_VARIANCE = 0.05        # EKF_STATUS_REPORT's normalised variances, aided
VARIANCE_GROWTH = 0.1          # per s without horizontal aiding
VARIANCE_MAX = 2.0
INFO, WARNING = 6, 4           # MAV_SEVERITY


class Aiding:
    """One boot's EKF. `update(t, navigation_ok, depth_healthy, measured)` every main-loop pass (t: time since
    boot) gives the estimate (eta, nu); texts to send are queued in `texts`."""

    def __init__(self, navigation_ok: bool = True):
        self.lost_since: float | None = None if navigation_ok else -AID_NONE_AFTER   # booted without it: AID_NONE
        self.texts: list[tuple[int, str]] = []
        self._held: np.ndarray | None = None         # north, east held in AID_NONE
        self._depth: float | None = None             # depth held while the sensor has failed
        self._last: tuple[np.ndarray, np.ndarray] | None = None

    def _lost_for(self, t: float) -> float:
        return 0.0 if self.lost_since is None else t - self.lost_since

    @property
    def const_pos(self) -> bool:
        return self._held is not None

    def update(self, t: float, navigation_ok: bool, depth_healthy: bool, measured) -> tuple[np.ndarray, np.ndarray]:
        if navigation_ok and depth_healthy and self.lost_since is None and self._depth is None:
            self._last = measured                     # aided and healthy: the measured state itself
            return measured
        eta, nu = (np.array(a, dtype=float) for a in measured)
        if navigation_ok and self.lost_since is not None:
            if self._held is not None:
                self.texts += [(INFO, "EKF3 IMU0 is using external nav data"),
                               (INFO, f"EKF3 IMU0 initial pos NED = {eta[0]:3.1f},{eta[1]:3.1f},{eta[2]:3.1f} (m)")]
            self.lost_since, self._held = None, None
        elif not navigation_ok and self.lost_since is None:
            self.lost_since = t
        if self.lost_since is not None and self._held is None and self._lost_for(t) >= AID_NONE_AFTER:
            last = self._last[0] if self._last is not None else eta
            self._held = np.array(last[:2], dtype=float)
            if self.lost_since > -AID_NONE_AFTER:          # it had been aiding: ArduPilot says it stopped
                self.texts.append((WARNING, "EKF3 IMU0 stopped aiding"))
        if self._held is not None:
            eta[:2] = self._held
            nu[:3] = _without_horizontal_velocity(eta, nu[:3])
        if depth_healthy:
            self._depth = None
        else:
            if self._depth is None:
                self._depth = float((self._last[0] if self._last is not None else eta)[2])
            eta[2] = self._depth
        self._last = (eta, nu)
        return eta, nu

    def flags(self, t: float) -> int:
        if self._held is not None:
            return CONST_POS_FLAGS
        if self.lost_since is not None and self._lost_for(t) >= POS_TIMEOUT:
            return TIMED_OUT_FLAGS
        return HEALTHY_FLAGS

    def variances(self, t: float) -> tuple[float, float, float, float]:
        """(velocity, horizontal position, vertical position, compass) as EKF_STATUS_REPORT gives them."""
        grown = min(HEALTHY_VARIANCE + VARIANCE_GROWTH * self._lost_for(t), VARIANCE_MAX) \
            if self.lost_since is not None else HEALTHY_VARIANCE
        return grown, grown, HEALTHY_VARIANCE, HEALTHY_VARIANCE

    def position_ok(self, t: float, armed: bool) -> bool:
        """`Sub::ekf_position_ok`: armed, an absolute horizontal position outside constant position mode; disarmed,
        a predicted one will do."""
        flags = self.flags(t)
        if armed:
            return bool(flags & POS_HORIZ_ABS) and not flags & CONST_POS_MODE
        return bool(flags & PRED_POS_HORIZ_ABS)


def _without_horizontal_velocity(eta: np.ndarray, v_body: np.ndarray) -> np.ndarray:
    """The body velocity whose NED velocity keeps only its vertical part (constant position mode)."""
    r = rotation(eta)
    v_ned = r @ v_body
    v_ned[:2] = 0.0
    return r.T @ v_ned
