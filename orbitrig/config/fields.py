"""Units, names, the field types and the bases shared by the configuration models."""

from __future__ import annotations

import re
from typing import Annotated, Literal, get_args

from pydantic import BaseModel, ConfigDict, Field, PrivateAttr, Strict

from drives.registers import MAX_DEVICE_ID, MIN_DEVICE_ID
from orbitrig.load_systems import LMS  # noqa: F401 - the configuration's names
from rigunits import DAY, MPA, RPM  # noqa: F401 - the configuration's names


#: the A/D board's eight channels, in frame order (forces of the two load systems, then the probes)
ChannelName = Literal["fx_piezo", "fy_piezo", "fx_strain", "fy_strain", "x_a", "y_a", "x_b", "y_b"]
CHANNEL_NAMES: tuple[str, ...] = get_args(ChannelName)
MODELS = ("kc7", "kc8", "kcd11", "kcd12")
FREQ_DEP = re.compile(r"^(none|power:auto|power:[1-9]\d*|power:[1-9]\d*,[1-9]\d*,[1-9]\d*|poly:[1-9]\d*)$")


class ConfigModel(BaseModel):
    """A table of a configuration file: unknown keys refused, frozen; every float finite (inf/nan
    refused with the file, line and key); strict: a number, a whole number or a boolean must be
    one in the file ("0.1", "1", "yes", 50.0 for a count are refused, not converted; an integer
    is a number: 1000 for 1000.0)."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False, strict=True)


class FileConfig(ConfigModel):
    """A configuration read from a file (orbitrig.config builds it): the file's name and its
    text as read. A model built otherwise names a placeholder: its own ``_file`` default."""

    _file: str = PrivateAttr("<config>")
    _text: str = PrivateAttr("")

    @property
    def file(self) -> str:
        return self._file

    @property
    def text(self) -> str:
        return self._text

    def remember_file(self, file: str, text: str) -> None:
        """Name the file this configuration was read from and keep its text as read (the readers of
        orbitrig.config, once the model is validated)."""
        self._file = file
        self._text = text


#: an Enum field of a strict model read from its value, as the file writes it (``Annotated[Whirl, BY_VALUE]``)
BY_VALUE = Strict(False)


Pos = Annotated[float, Field(gt=0)]
NonNeg = Annotated[float, Field(ge=0)]
#: a time (s) that must pass: positive, at most one day
Seconds = Annotated[float, Field(gt=0, le=DAY)]
#: a time (s) that may be zero, at most one day
Wait = Annotated[float, Field(ge=0, le=DAY)]
#: a speed of the rig's drives (rpm)
Rpm = Annotated[float, Field(gt=0, le=100_000)]
#: an orbit ratio |Omega|/omega
Ratio = Annotated[float, Field(gt=0, le=100)]
#: a pressure (MPa)
Mpa = Annotated[float, Field(gt=0, le=1_000)]
#: a Modbus device id (1..247; 0 is broadcast)
DeviceId = Annotated[int, Field(ge=MIN_DEVICE_ID, le=MAX_DEVICE_ID)]
