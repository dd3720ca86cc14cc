"""Exceptions of the acquisition layer (root: ``rigerrors.OrbitrigError``)."""

from __future__ import annotations

from rigerrors import OrbitrigError


class DaqError(OrbitrigError):
    """Any acquisition failure (A/D board link, CAN node, bad configuration)."""


class DaqLinkError(DaqError):
    """The byte link to the A/D board (serial port, pty, TCP) cannot be opened or dropped."""


class DaqTimeoutError(DaqError, TimeoutError):
    """Not enough good revolutions (or no data at all) arrived within the timeout; ``heard``:
    bytes came from the board meanwhile (False: it sent nothing)."""

    def __init__(self, message: str, *, heard: bool = False) -> None:
        super().__init__(message)
        self.heard = heard
