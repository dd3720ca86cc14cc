"""A drive's speed over simulated time: knots (s, rpm), linear between them.

The drive model adds a knot wherever its speed's slope changes (a ramp's phase ends, a
command arrives) and at every integration's end; a held speed keeps two knots, the last
moved on. The slot stream reads the speed at any time since its last tick from it
(`at`), so a tick that a stalled simulator made long still turns the orbit spindle as
the drive did within it, not at the mean of its two ends.
"""

from __future__ import annotations

from collections import deque

import numpy as np

#: knots kept: ramps add one per request and phase; a hold keeps two
KNOTS = 512
#: s between the two knots of a jump (a keypad's speed set at once)
JUMP_S = 1e-9


class SpeedTrace:
    """The speed (rpm, signed) from simulated time `t` (s) on: `speed` until a knot is added."""

    def __init__(self, t: float, speed: float = 0.0):
        self._knots: deque[tuple[float, float]] = deque([(t, speed)], maxlen=KNOTS)

    def add(self, t: float, speed: float) -> None:
        """The speed is `speed` at `t` (s; not before the last knot), linear from the last knot."""
        last_t, last = self._knots[-1]
        t = max(t, last_t)
        if len(self._knots) >= 2 and self._knots[-2][1] == last == speed:
            self._knots[-1] = (t, speed)  # held: the hold's end moves on
        else:
            self._knots.append((t, speed))

    def jump(self, t: float, speed: float) -> None:
        """The speed set at once at `t` (s): the speed before held up to `t`, `speed` after."""
        self.add(t, self._knots[-1][1])
        self.add(t + JUMP_S, speed)

    def at(self, times: np.ndarray) -> np.ndarray:
        """rpm at simulated `times` (s): linear between knots, the first/last knot's outside them."""
        t, v = np.asarray(self._knots).T
        out: np.ndarray = np.interp(times, t, v)
        return out

    def times(self) -> np.ndarray:
        """The knots' times (s)."""
        return np.asarray([k[0] for k in self._knots])
