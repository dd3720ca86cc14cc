"""The rig's stated calibration uncertainty (rig.toml ``[calibration_uncertainty]``).

One standard uncertainty (type B) per channel and error kind, in the units an
operator reads: gain in percent, phase in degrees, time delay in microseconds,
and the displacement probes' sensitivity in percent. The systematic uncertainty
budget of every identified coefficient is propagated from these (SI through the
properties: relative, rad, s).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Annotated

from pydantic import Field, create_model

from orbitrig.config.fields import CHANNEL_NAMES, _Model

#: a relative standard uncertainty in percent
Percent = Annotated[float, Field(ge=0, le=50)]
#: a phase standard uncertainty in degrees
Degrees = Annotated[float, Field(ge=0, le=30)]
#: a time-delay standard uncertainty in microseconds
Microseconds = Annotated[float, Field(ge=0, le=100_000)]


class ChannelUncertainty(_Model):
    """Standard uncertainty of one channel's calibration."""

    gain_pct: Percent = 0.0
    phase_deg: Degrees = 0.0
    delay_us: Microseconds = 0.0

    @property
    def gain(self) -> float:
        """Relative gain uncertainty (1)."""
        return self.gain_pct / 100.0

    @property
    def phase(self) -> float:
        """Phase uncertainty (rad)."""
        return math.radians(self.phase_deg)

    @property
    def delay(self) -> float:
        """Time-delay uncertainty (s)."""
        return self.delay_us * 1e-6


class _Stated(_Model):
    """The uncertainty common to every probe (the first key of the table)."""

    probe_sensitivity_pct: Percent = 0.0


# one field per A/D channel, named and ordered as fields.ChannelName (the TOML table
# [calibration_uncertainty.NAME] of each, after probe_sensitivity_pct): a channel named there has its field here
if TYPE_CHECKING:
    _PerChannel = _Stated
else:
    _PerChannel = create_model(
        "_PerChannel",
        __base__=_Stated,
        __module__=__name__,
        **{name: (ChannelUncertainty, ChannelUncertainty()) for name in CHANNEL_NAMES},
    )


class CalibrationUncertainty(_PerChannel):
    """Every channel's calibration uncertainty (a field per channel of fields.ChannelName, each
    ChannelUncertainty; a channel left out: zero) and the probes' sensitivity uncertainty (one
    error common to every probe: the probe calibration's reference; the budget takes x and y fully
    correlated)."""

    @property
    def probe_sensitivity(self) -> float:
        """Relative sensitivity uncertainty of the displacement probes, common to all (1)."""
        return self.probe_sensitivity_pct / 100.0

    def channel(self, name: str) -> ChannelUncertainty:
        """The uncertainty of channel ``name`` (one of CHANNEL_NAMES; KeyError for another)."""
        if name not in CHANNEL_NAMES:
            raise KeyError(name)
        found: ChannelUncertainty = getattr(self, name)
        return found
