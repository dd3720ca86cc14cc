"""Exceptions of the acquisition layer (root: ``rigerrors.OrbitrigError``)."""

from __future__ import annotations

from rigerrors import OrbitrigError


class DaqError(OrbitrigError):
    """Any acquisition failure (A/D board link, CAN node, bad configuration)."""


class DaqLinkError(DaqError):
    """The byte link to the A/D board (serial port, pty, TCP) cannot be opened or dropped."""


class DaqTimeoutError(DaqError, TimeoutError):
    """Not enough good revolutions (or no data at all) arrived within the timeout; ``heard``:
    bytes came from the board meanwhile (False: it sent nothing); ``orbit_measured``: the orbit
    speed (rad/s) the timing disk measured on revolutions left out for being off the set one."""

    def __init__(self, message: str, *, heard: bool = False, orbit_measured: float | None = None) -> None:
        super().__init__(message)
        self.heard = heard
        self.orbit_measured = orbit_measured
