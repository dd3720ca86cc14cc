"""A bounded, thread-safe memo for what depends on a design only (orbit frequencies and
shapes, a model), not on measured numbers: a sweep or a Monte Carlo identifies many tables
of one design, and the ranks of its idealised, reference and yardstick designs are the
same for all of them; also what depends on the board's angles only (reduction.runout_slip's
solver of each revolution's spin harmonics, one for all of a block's revolutions)."""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Callable, Hashable
from typing import Generic, TypeVar

V = TypeVar("V")

DESIGN_MEMO_ROWS = 1024  # designs of up to this many orbits are memoised (their keys stay small)


class DesignMemo(Generic[V]):
    """The last ``size`` values by key (least recently used dropped). A value must not be
    changed by its users (Ranks are stored with read-only arrays)."""

    def __init__(self, size: int) -> None:
        self._size = size
        self._values: OrderedDict[Hashable, V] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, key: Hashable, compute: Callable[[], V]) -> V:
        """The value kept for ``key``, else ``compute()`` (outside the lock), kept."""
        with self._lock:
            if key in self._values:
                self._values.move_to_end(key)
                return self._values[key]
        value = compute()
        with self._lock:
            self._values[key] = value
            while len(self._values) > self._size:
                self._values.popitem(last=False)
        return value
