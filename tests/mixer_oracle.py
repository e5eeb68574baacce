"""ArduSub's own mixer table for the Heavy, written out from its source as the tests' oracle (not from our
`rov_mav.model.frames`, which it checks)."""

from __future__ import annotations

import numpy as np

# ArduSub AP_Motors6DOF, SUB_FRAME_VECTORED_6DOF: (roll, pitch, yaw, throttle, forward, lateral) per motor.
ARDUSUB_FACTORS = np.array([
    [0, 0, +1, 0, -1, +1],
    [0, 0, -1, 0, -1, -1],
    [0, 0, -1, 0, +1, +1],
    [0, 0, +1, 0, +1, -1],
    [+1, -1, 0, -1, 0, 0],
    [-1, -1, 0, -1, 0, 0],
    [+1, +1, 0, -1, 0, 0],
    [-1, +1, 0, -1, 0, 0],
], dtype=float)
ROLL, PITCH, YAW, THROTTLE, FORWARD, LATERAL = range(6)
