"""The allowed speed range of the two spindles (rad/s) and how messages state a speed."""

from __future__ import annotations

import math
from dataclasses import dataclass

from drives import registers as R
from drives.errors import DriveLimitError
from rigunits import in_rpm


def fmt_speed(speed: float) -> str:
    """A speed in rad/s as messages give it: rad/s, with rpm in brackets."""
    return f"{speed:.3f} rad/s ({in_rpm(speed):.1f} rpm)"


@dataclass(frozen=True)
class DriveLimits:
    """Allowed operating range, rad/s.

    max_spin : largest spin speed omega (spin is >= 0).
    max_orbit : largest |Omega| (orbit is signed).
    min_ratio, max_ratio : allowed |Omega| / omega while both turn, None =
        unbounded. Omega = 0 (orbit spindle still) passes; omega = 0 with
        Omega != 0 (orbit without spin, ratio infinite) fails any ratio bound.
    """

    max_spin: float
    max_orbit: float
    min_ratio: float | None = None
    max_ratio: float | None = None

    def __post_init__(self) -> None:
        for name, value in (
            ("max_spin", self.max_spin),
            ("max_orbit", self.max_orbit),
            ("min_ratio", self.min_ratio),
            ("max_ratio", self.max_ratio),
        ):
            if value is not None and not value >= 0:
                raise ValueError(f"DriveLimits.{name} = {value} must be >= 0")
        if self.min_ratio is not None and self.max_ratio is not None:
            if self.min_ratio > self.max_ratio:
                raise ValueError(f"DriveLimits.min_ratio = {self.min_ratio} > max_ratio = {self.max_ratio}")

    def check(self, spin: float, orbit: float, *, spin_id: int = 1, orbit_id: int = 2) -> None:
        """Raise DriveLimitError if (spin, orbit) is outside the limits (pure)."""
        if not (math.isfinite(spin) and math.isfinite(orbit)):
            raise DriveLimitError(f"speeds must be finite (spin {spin}, orbit {orbit})")
        if spin < 0:
            raise DriveLimitError(
                f"spin {fmt_speed(spin)} is negative; the spin drive turns one way only",
                drive=spin_id,
                drive_name="spin",
                register=R.REF,
            )
        if spin > self.max_spin:
            raise DriveLimitError(
                f"spin {fmt_speed(spin)} exceeds the limit max_spin = {fmt_speed(self.max_spin)}",
                drive=spin_id,
                drive_name="spin",
                register=R.REF,
            )
        if abs(orbit) > self.max_orbit:
            raise DriveLimitError(
                f"orbit |{fmt_speed(orbit)}| exceeds the limit max_orbit = {fmt_speed(self.max_orbit)}",
                drive=orbit_id,
                drive_name="orbit",
                register=R.REF,
            )
        if self.min_ratio is None and self.max_ratio is None or orbit == 0:
            return
        ratio = math.inf if spin == 0 else abs(orbit) / spin
        lo = self.min_ratio if self.min_ratio is not None else 0.0
        hi = self.max_ratio if self.max_ratio is not None else math.inf
        if not lo <= ratio <= hi or math.isinf(ratio):
            raise DriveLimitError(
                f"|Omega|/omega = {ratio:.4g} (orbit {fmt_speed(orbit)}, spin {fmt_speed(spin)}) "
                f"is outside the allowed range [{lo:g}, {hi:g}]"
            )
