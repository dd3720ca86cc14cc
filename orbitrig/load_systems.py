"""The rig's two load measuring systems (piezoelectric load cells and strain-gauge links):
their names in files, payloads and channel names (fx_piezo, fy_strain ...), in table order, and
the one convention of their difference (:data:`DIFFERENCE`)."""

from __future__ import annotations

from enum import StrEnum
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # numpy is imported where a difference is computed: the command line loads this
    import numpy as np


class LoadSystem(StrEnum):
    PIEZO = "piezo"
    STRAIN = "strain"


LMS: tuple[LoadSystem, ...] = tuple(LoadSystem)  # the order of tables and rows in run.h5

#: (a, b) of every difference of the two systems, a − b relative to |a|: the report's consistency
#: table and E_n = (a − b)/u(a − b), the signals and LMS figures' amplitude and phase differences
DIFFERENCE: tuple[LoadSystem, LoadSystem] = (LoadSystem.PIEZO, LoadSystem.STRAIN)
#: the difference in words, as the report's tables and figures name it
DIFFERENCE_WORDS = f"{DIFFERENCE[0]} \u2212 {DIFFERENCE[1]}"


def relative_difference(a, b) -> tuple[np.ndarray, np.ndarray]:
    """Amplitude ((|a| − |b|)/|a|, a fraction) and phase (phase(a) − phase(b), rad in (−π, π]) of
    force phasors `a` and `b` of the two systems in :data:`DIFFERENCE`'s order (scalars or arrays)."""
    import numpy as np

    a, b = np.asarray(a), np.asarray(b)
    return (np.abs(a) - np.abs(b)) / np.abs(a), np.angle(a / b)
