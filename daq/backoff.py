"""Growing, jittered delays between reconnect attempts.

Attempt k (k = 0, 1, ...) after a link was lost waits a delay drawn uniformly in
[d_k / 2, d_k], d_k = min(initial * factor^k, maximum) (s). The count starts
again from ``initial`` only when ``reset`` is called, which a reader does once
data has flowed on the new link: a peer that accepts and closes at once keeps
the delays growing instead of being hammered in a tight loop.
"""

from __future__ import annotations

import random


class Backoff:
    """Delays (s) for successive reconnect attempts; ``rng`` for reproducible jitter."""

    def __init__(
        self, initial: float = 0.05, maximum: float = 2.0, factor: float = 2.0, rng: random.Random | None = None
    ) -> None:
        if not (0 < initial <= maximum < float("inf")) or not factor >= 1:
            raise ValueError(f"backoff: need 0 < initial ({initial}) <= maximum ({maximum}) < inf, factor >= 1")
        self.initial, self.maximum, self.factor = initial, maximum, factor
        self._rng = rng or random.Random()
        self.attempts = 0  # attempts since the last reset

    def ceiling(self) -> float:
        """Upper bound d_k (s) of the next delay."""
        return min(self.initial * self.factor ** min(self.attempts, 64), self.maximum)

    def next_delay(self) -> float:
        """The delay (s) before the next attempt; counts the attempt."""
        d = self.ceiling()
        self.attempts += 1
        return d * self._rng.uniform(0.5, 1.0)

    def reset(self) -> None:
        """Data flowed: the next loss starts again from ``initial``."""
        self.attempts = 0
