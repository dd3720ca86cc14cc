"""The simulator's random numbers, all of them from the scenario's seed: one stream per purpose,
spawned from one numpy SeedSequence (the one owner), so that what a seed draws does not depend on
what else was drawn before, nor on how the A/D board's ticks cut the slot edges.

Per-sample draws (white noise, slot-edge jitter) are keyed by the global slot index g (slot edges
since the board started) through a counter-based generator (Philox: key from the purpose's stream,
counter from the revolution g // 360 and the channel): the draw at slot edge g is the same whatever
tick converts it and whatever was converted before. Which slot edges a run converts at which
simulated time still follows the wall-clock timing of the commands (docs/simulator.md).
"""

from __future__ import annotations

import enum

import numpy as np

SLOTS = 360  # slot edges per orbit revolution (the timing disk)


class Purpose(enum.IntEnum):
    """What a stream is drawn for (its spawn key: never renumber, only append)."""

    PHASES = 0  # the disturbances' random phases and the speed ripple's, drawn once at construction
    START = 1  # where in the revolution the board starts counting slot edges
    WHITE = 2  # white noise per channel and slot edge
    JITTER = 3  # slot-edge jitter per slot edge (shared by the channels converted at it)
    BIT_ERRORS = 4  # where a corrupted frame's bit flips


class SeedStreams:
    """Every random stream of one simulated rig, from ``seed`` (an int)."""

    def __init__(self, seed: int):
        self.seed = int(seed)
        self._keys: dict[Purpose, np.ndarray] = {}

    def _sequence(self, purpose: Purpose) -> np.random.SeedSequence:
        return np.random.SeedSequence(self.seed, spawn_key=(int(purpose),))

    def generator(self, purpose: Purpose) -> np.random.Generator:
        """A fresh sequential stream of ``purpose`` (the same numbers every time it is asked for)."""
        return np.random.Generator(np.random.PCG64(self._sequence(purpose)))

    def slot_normals(self, purpose: Purpose, channel: int, g: np.ndarray) -> np.ndarray:
        """Standard normal draws at global slot indices ``g`` (ints, any order) of ``channel``
        (-1: one shared by all channels): a function of (seed, purpose, channel, g) only."""
        key = self._keys.get(purpose)
        if key is None:
            key = self._keys[purpose] = self._sequence(purpose).generate_state(2, np.uint64)
        g = np.asarray(g, dtype=np.int64)
        out = np.empty(g.shape)
        if not g.size:
            return out
        rev, slot = np.divmod(g, SLOTS)
        first, last = int(rev.min()), int(rev.max())
        if last == first:  # the common case: one revolution's slots
            return self._revolution(key, channel, first)[slot]
        for r in np.unique(rev):
            sel = rev == r
            out[sel] = self._revolution(key, channel, int(r))[slot[sel]]
        return out

    @staticmethod
    def _revolution(key: np.ndarray, channel: int, rev: int) -> np.ndarray:
        """The SLOTS normals of revolution ``rev`` (counter words 1 and 2: far apart from the
        draws' own counting in word 0)."""
        counter = np.array([0, rev % 2**64, channel % 2**64, 0], dtype=np.uint64)
        return np.random.Generator(np.random.Philox(key=key, counter=counter)).standard_normal(SLOTS)
