"""The simulator's random numbers, all of them from the scenario's seed: one stream per purpose,
spawned from one numpy SeedSequence (the one owner), so that what a seed draws does not depend on
what else was drawn before, nor on how the A/D board's ticks cut the slot edges.

Per-sample draws (white noise, slot-edge jitter) are keyed by the global slot index g (slot edges
since the board started) through a counter-based generator (SplitMix64 at position g from a start
drawn from the purpose's stream and the channel): the draw at slot edge g is the same whatever tick
converts it and whatever was converted before. Which slot edges a run converts at which
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
        self._starts: dict[tuple[Purpose, int], np.uint64] = {}

    def _sequence(self, purpose: Purpose) -> np.random.SeedSequence:
        return np.random.SeedSequence(self.seed, spawn_key=(int(purpose),))

    def generator(self, purpose: Purpose) -> np.random.Generator:
        """A fresh sequential stream of ``purpose`` (the same numbers every time it is asked for)."""
        return np.random.Generator(np.random.PCG64(self._sequence(purpose)))

    def slot_normals(self, purpose: Purpose, channel: int, g: np.ndarray) -> np.ndarray:
        """Standard normal draws at global slot indices ``g`` (ints, any order) of ``channel``
        (-1: one shared by all channels): a function of (seed, purpose, channel, g) only.

        Counter-based: the SplitMix64 sequence of a start drawn from the purpose's stream and the
        channel, at position g, through Box-Muller (32 bits each for the radius and the angle: the
        tail cut at 6.7 sigma). Each draw costs its own few operations, whatever else is drawn."""
        g = np.asarray(g, dtype=np.int64)
        start = self._starts.get((purpose, channel))
        if start is None:
            key = self._sequence(purpose).generate_state(1, np.uint64)
            spread = (int(key[0]) + (channel % 2**64) * int(_ODD)) % 2**64  # Python ints: no wrap warning
            start = self._starts[(purpose, channel)] = _mix(np.array([spread], np.uint64))[0]
        z = g.astype(np.uint64)
        z *= _GAMMA
        z += start
        _mix(z)
        radius = (z >> _U32).astype(np.float64)
        z &= _LOW32
        angle = z.astype(np.float64)
        for u in (radius, angle):  # the 32-bit halves as uniforms in (0, 1)
            u += 0.5
            u *= 2.0**-32
        np.log(radius, out=radius)
        radius *= -2.0
        np.sqrt(radius, out=radius)
        angle *= 2.0 * np.pi
        np.cos(angle, out=angle)
        radius *= angle
        return radius


_GAMMA = np.uint64(0x9E3779B97F4A7C15)  # SplitMix64's increment (the golden ratio's 64 bits)
_ODD = np.uint64(0xD1B54A32D192ED03)  # spreads the channels' starts before they are mixed
_ROUNDS = ((np.uint64(30), np.uint64(0xBF58476D1CE4E5B9)), (np.uint64(27), np.uint64(0x94D049BB133111EB)))
_LAST = np.uint64(31)  # the finaliser's last shift
_U32, _LOW32 = np.uint64(32), np.uint64(0xFFFFFFFF)  # the halves of a 64-bit draw


def _mix(z: np.ndarray) -> np.ndarray:
    """SplitMix64's finaliser of ``z`` (uint64, wrapping), in place and returned: a bijection whose
    outputs pass as random."""
    for shift, factor in _ROUNDS:
        z ^= z >> shift
        z *= factor
    z ^= z >> _LAST
    return z
