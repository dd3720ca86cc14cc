"""Whirl direction of the imposed orbit: its name in files and payloads, and its sign.

Forward whirl turns with the spin (orbit speed Omega > 0 on the drive side), backward against it.
"""

from __future__ import annotations

from enum import StrEnum


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
