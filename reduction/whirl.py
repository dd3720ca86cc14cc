"""Whirl direction of the imposed orbit: its name in files and payloads, and its sign; and the
directions a list of orbit frequencies is run in.

Forward whirl turns with the spin (orbit speed Omega > 0 on the drive side), backward against it;
measured, a forward orbit turns from +x towards +y (`whirl_sense`).
"""

from __future__ import annotations

from collections.abc import Iterable
from enum import StrEnum
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # numpy only where a sense is measured: the command line starts without it
    import numpy as np
    from numpy.typing import ArrayLike


class Whirl(StrEnum):
    FORWARD = "forward"
    BACKWARD = "backward"

    @property
    def sign(self) -> int:
        """+1 forward, -1 backward: the sign of the orbit speed."""
        return 1 if self is Whirl.FORWARD else -1

    @classmethod
    def of(cls, sign: float) -> Whirl:
        """The direction of a signed orbit speed or direction (> 0 forward, else backward)."""
        return cls.FORWARD if sign > 0 else cls.BACKWARD


class Directions(StrEnum):
    """The whirl directions each orbit frequency of a list is run in, one block per direction:
    its name in designs, records and payloads."""

    FORWARD = "forward"
    BACKWARD = "backward"
    BOTH = "both"

    @property
    def blocks(self) -> int:
        """Blocks per orbit frequency: 2 for both directions, else 1."""
        return 2 if self is Directions.BOTH else 1

    @property
    def whirls(self) -> tuple[Whirl, ...]:
        """The directions run, forward first."""
        return (Whirl.FORWARD, Whirl.BACKWARD) if self is Directions.BOTH else (Whirl(self.value),)

    @classmethod
    def of(cls, whirls: Iterable[str]) -> Directions:
        """BOTH when `whirls` holds forward and backward, else the one it holds (ValueError
        when it holds none or a name that is not a whirl direction)."""
        found = {Whirl(w) for w in whirls}
        if not found:
            raise ValueError("no whirl direction given")
        return cls.BOTH if len(found) == 2 else cls(found.pop().value)


def whirl_sense(x: ArrayLike, y: ArrayLike) -> np.ndarray:
    """How the orbit of displacement phasors x, y (m) turns: -Im(conj(x) y) / (|x| |y|), +1 a
    forward circle (from +x towards +y), -1 a backward one, 0 a line (or no motion)."""
    import numpy as np

    xa, ya = np.asarray(x, dtype=complex), np.asarray(y, dtype=complex)
    scale = np.abs(xa) * np.abs(ya)
    cross = -np.imag(np.conj(xa) * ya)
    sense: np.ndarray = np.divide(cross, scale, out=np.zeros_like(cross), where=scale > 0)
    return sense
