"""`rov-mav run --realtime`: ask the operating system to keep the control loop running on a busy computer.

A companion computer that is also encoding video can leave the loop unscheduled for hundreds of milliseconds, and on
RCIN passthrough the thrusters hold the last command meanwhile. Real-time scheduling (SCHED_FIFO, above every normal
process) and locked memory (no page faults on the loop's path) are what Linux offers; both need privileges
(CAP_SYS_NICE and CAP_IPC_LOCK, or root, or limits raised in /etc/security/limits.conf: rtprio, memlock).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os

PRIORITY = 20            # SCHED_FIFO priority: above normal processes, below the kernel's own threads (50+)
MCL_CURRENT, MCL_FUTURE = 1, 2


def ask_realtime() -> tuple[bool, str]:
    """Ask for SCHED_FIFO and locked memory for this process; (all granted, one line saying what was and wasn't)."""
    granted, refused = [], []
    try:
        # SCHED_RESET_ON_FORK: a child (the built-in vehicle) starts at normal priority
        os.sched_setscheduler(0, os.SCHED_FIFO | os.SCHED_RESET_ON_FORK, os.sched_param(PRIORITY))
        granted.append(f"SCHED_FIFO priority {PRIORITY}")
    except (OSError, AttributeError) as exc:
        refused.append(f"real-time scheduling ({_why(exc)})")
    libc = ctypes.CDLL(ctypes.util.find_library("c"), use_errno=True)
    if libc.mlockall(MCL_CURRENT | MCL_FUTURE) == 0:
        granted.append("memory locked")
    else:
        refused.append(f"locked memory ({os.strerror(ctypes.get_errno())})")
    if refused:
        return False, ("--realtime: refused: " + "; ".join(refused) + (f" (granted: {', '.join(granted)})"
                       if granted else "") + ": the loop runs at normal priority and may stall on a busy computer "
                       "(needs root, or CAP_SYS_NICE and CAP_IPC_LOCK, or rtprio and memlock limits)")
    return True, "--realtime: " + " and ".join(granted)


def _why(exc: Exception) -> str:
    return exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
