"""How the A/D board scans its channels (docs/protocols/adc-frames.md). No numerics: the
application's configuration and command line name the modes without loading numpy.

- ``sequential``: one sample per slot, channel k at slots k, k+C, k+2C, ... (C divides 360);
- ``simultaneous``: every channel sampled at every slot (C samples per slot).
"""

from __future__ import annotations

from enum import StrEnum

#: slots of the timing disk in one orbit revolution: the A/D board converts one sample a slot
#: (a channel each in sequential mode, every channel in simultaneous mode)
SLOTS_PER_REV = 360


class AdcMode(StrEnum):
    """The board's scan mode; the value is the word of the rig configuration and ``--mode``."""

    SEQUENTIAL = "sequential"
    SIMULTANEOUS = "simultaneous"
