"""A logged series read at other times: each time takes the last value known then (a zero-order hold)."""

from __future__ import annotations

import numpy as np


def last_known(t_source: np.ndarray, values: np.ndarray, t: np.ndarray) -> np.ndarray:
    """`values` (logged at `t_source`, in any order) sampled at `t`, each the last known (the first before any)."""
    order = np.argsort(t_source, kind="stable")
    k = np.clip(np.searchsorted(t_source[order], t, side="right") - 1, 0, len(order) - 1)
    return values[order][k]
