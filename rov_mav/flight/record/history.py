"""What a run keeps of every tick for its final metrics: named float columns in arrays that double when full, so a
long dive costs a few hundred bytes per tick (not a Python object per value) and appending stays O(1)."""

from __future__ import annotations

import numpy as np


class History:
    """Rows of named float columns of fixed widths, e.g. History(t=1, eta=6)."""

    def __init__(self, capacity: int = 4096, **widths: int):
        self.widths = widths
        self.size = 0
        self._data = {name: np.empty((capacity, width)) for name, width in widths.items()}

    def append(self, **row) -> None:
        if self.size == len(next(iter(self._data.values()))):
            self._data = {name: np.concatenate([a, np.empty_like(a)]) for name, a in self._data.items()}
        for name, a in self._data.items():
            a[self.size] = row[name]
        self.size += 1

    def column(self, name: str) -> np.ndarray:
        """A copy of the rows so far: (N,) for a width-1 column, else (N, width)."""
        a = self._data[name][:self.size].copy()
        return a[:, 0] if self.widths[name] == 1 else a
