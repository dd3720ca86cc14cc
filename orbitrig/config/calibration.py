"""The rig's stated calibration uncertainty (rig.toml ``[calibration_uncertainty]``).

One standard uncertainty (type B) per channel and error kind, in the units an
operator reads: gain in percent, phase in degrees, time delay in microseconds,
and the displacement probes' sensitivity in percent. The systematic uncertainty
budget of every identified coefficient is propagated from these (SI through the
properties: relative, rad, s).
"""

from __future__ import annotations

import math
from typing import Annotated

from pydantic import Field

from orbitrig.config.fields import _Model

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


class CalibrationUncertainty(_Model):
    """Every channel's calibration uncertainty (a channel left out: zero) and the
    probes' sensitivity uncertainty (one error common to every probe: the probe calibration's
    reference; the budget takes x and y fully correlated)."""

    probe_sensitivity_pct: Percent = 0.0
    fx_piezo: ChannelUncertainty = ChannelUncertainty()
    fy_piezo: ChannelUncertainty = ChannelUncertainty()
    fx_strain: ChannelUncertainty = ChannelUncertainty()
    fy_strain: ChannelUncertainty = ChannelUncertainty()
    x_a: ChannelUncertainty = ChannelUncertainty()
    y_a: ChannelUncertainty = ChannelUncertainty()
    x_b: ChannelUncertainty = ChannelUncertainty()
    y_b: ChannelUncertainty = ChannelUncertainty()

    @property
    def probe_sensitivity(self) -> float:
        """Relative sensitivity uncertainty of the displacement probes, common to all (1)."""
        return self.probe_sensitivity_pct / 100.0

    def channel(self, name: str) -> ChannelUncertainty:
        """The uncertainty of channel ``name`` (one of CHANNEL_NAMES)."""
        return {
            "fx_piezo": self.fx_piezo,
            "fy_piezo": self.fy_piezo,
            "fx_strain": self.fx_strain,
            "fy_strain": self.fy_strain,
            "x_a": self.x_a,
            "y_a": self.y_a,
            "x_b": self.x_b,
            "y_b": self.y_b,
        }[name]
