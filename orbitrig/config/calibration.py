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

from orbitrig.config.fields import CHANNEL_NAMES, ChannelName, ConfigModel
from rigunits import US

#: a relative standard uncertainty in percent
Percent = Annotated[float, Field(ge=0, le=50)]
#: a phase standard uncertainty in degrees
Degrees = Annotated[float, Field(ge=0, le=30)]
#: a time-delay standard uncertainty in microseconds
Microseconds = Annotated[float, Field(ge=0, le=100_000)]


class ChannelUncertainty(ConfigModel):
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
        return self.delay_us * US


class CalibrationUncertainty(ConfigModel):
    """Every channel's calibration uncertainty (a field per channel of fields.ChannelName, named
    and ordered as there, each ChannelUncertainty; a channel left out: zero) and the probes'
    sensitivity uncertainty (one error common to every probe: the probe calibration's reference;
    the budget takes x and y fully correlated). The TOML table is the fields in this order."""

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

    def channel(self, name: ChannelName) -> ChannelUncertainty:
        """The uncertainty of channel ``name`` (its field; KeyError for a name not in ChannelName)."""
        if name not in CHANNEL_NAMES:
            raise KeyError(name)
        found: ChannelUncertainty = getattr(self, name)
        return found


def _channels_are_fields(model: type[ConfigModel], first: tuple[str, ...]) -> None:
    """Refuse (at import) a model whose fields after ``first`` are not the channels of
    fields.ChannelName, each a ChannelUncertainty, in their order: a channel added there and
    not here would have no table in rig.toml or a record, and channel() no field for it."""
    names = tuple(model.model_fields)
    per_channel = names[len(first) :]
    if names[: len(first)] != first or per_channel != CHANNEL_NAMES:
        missing = [n for n in CHANNEL_NAMES if n not in per_channel]
        extra = [n for n in per_channel if n not in CHANNEL_NAMES]
        raise TypeError(
            f"{model.__name__}: its fields after {list(first)} must be fields.ChannelName's channels in order "
            f"{list(CHANNEL_NAMES)}; they are {list(per_channel)} (missing {missing}, not a channel {extra}): "
            "write a field for each channel"
        )
    wrong = [n for n in per_channel if model.model_fields[n].annotation is not ChannelUncertainty]
    if wrong:
        raise TypeError(f"{model.__name__}: channel fields {wrong} must each be a ChannelUncertainty")


_channels_are_fields(CalibrationUncertainty, ("probe_sensitivity_pct",))
