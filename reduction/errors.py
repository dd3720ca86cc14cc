"""Errors of the numerical layer (root: :class:`rigerrors.OrbitrigError`)."""

from __future__ import annotations


from rigerrors import OrbitrigError


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
