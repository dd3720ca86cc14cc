"""The rig's two load measuring systems (piezoelectric load cells and strain-gauge links):
their names in files, payloads and channel names (fx_piezo, fy_strain ...), in table order."""

from __future__ import annotations

from enum import StrEnum


class LoadSystem(StrEnum):
    PIEZO = "piezo"
    STRAIN = "strain"


LMS: tuple[LoadSystem, ...] = tuple(LoadSystem)  # the order of tables and rows in run.h5
