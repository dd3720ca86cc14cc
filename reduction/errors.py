"""Root of orbitrig's exception tree.

It lives here because ``reduction`` is the bottom layer: it imports nothing of
ours, so every other package (daq, drives, the application) may import this
one module without creating a cycle. ``sim`` does not use it: the simulator is
an independent stand-in for the hardware.
"""

from __future__ import annotations


class OrbitrigError(Exception):
    """Base class of every error orbitrig raises on purpose."""


class ReductionError(OrbitrigError, ValueError):
    """Bad input to a numerical routine (shape, range, unknown option)."""


class IdentificationError(ReductionError):
    """A model cannot be identified from the given orbit table."""


class IdentifiabilityError(IdentificationError):
    """The regression cannot separate some coefficients.

    Attributes
    ----------
    combinations : list[str]
        Human-readable linear combinations of coefficient names that the data
        cannot separate, e.g. ``"Kxx_1 - Cxy"`` (forward whirl only).
    """

    def __init__(self, message: str, combinations: list[str] | None = None):
        super().__init__(message)
        self.combinations = list(combinations or [])
