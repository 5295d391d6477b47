"""A small memo of recent values, for the inputs a fit or a path evaluates again and again.

The maps of a diagnosis' fits, the kinematics of a model's recent pose batches, a parallelogram's
Jacobians and compliances: each is a pure function of its key, evaluated thousands of times on the same
few keys.  :class:`Recent` keeps the values of the last few keys (the oldest dropped first) and is locked,
because ``vjm path`` evaluates one model from a thread pool.
"""
from __future__ import annotations

import threading
from typing import Callable, Hashable, TypeVar

T = TypeVar("T")


class Recent:
    """The values of the last ``size`` keys asked for, each computed once while it is kept."""

    def __init__(self, size: int):
        self.size = size
        self._lock = threading.Lock()
        self._values: dict = {}

    def get(self, key: Hashable, compute: Callable[[], T]) -> T:
        """The value kept under ``key``, else ``compute()`` kept under it (the oldest key dropped when full).
        ``compute`` runs outside the lock: two threads may compute the same value, never block each other."""
        with self._lock:
            hit = self._values.get(key)
        if hit is not None:
            return hit
        value = compute()
        with self._lock:
            if key not in self._values and len(self._values) >= self.size:
                self._values.pop(next(iter(self._values)))
            self._values[key] = value
        return value

    def clear(self) -> None:
        with self._lock:
            self._values.clear()

    def __len__(self) -> int:
        return len(self._values)
