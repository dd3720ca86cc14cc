"""The [drives] section of rig.toml: the spindles' speed limits and orbit ratio, the drives' device
ids, and the heartbeat (poll interval, request timeout, link-loss polls) fitted under the drives'
comm-loss watchdog; each bound the drives would refuse later (drives.registers) refused here."""

from __future__ import annotations

import math
import warnings
from typing import Annotated

from pydantic import Field, field_validator, model_validator

from drives import registers as R
from orbitrig.config.fields import DeviceId, Ratio, Rpm, ConfigModel
from orbitrig.config.messages import ConfigWarning


LINK_LOSS_MARGIN = 0.8  # [drives] link_loss_time_s above this share of comm_loss_timeout_s warns


class Drives(ConfigModel):
    max_spin_rpm: Rpm = 2500.0
    max_orbit_rpm: Rpm = 2500.0
    min_ratio: Annotated[float, Field(ge=0, le=100)] | None = None
    max_ratio: Ratio | None = None
    spin_id: DeviceId = 1
    orbit_id: DeviceId = 2
    poll_interval_s: Annotated[float, Field(gt=0, le=60)] = 0.1
    timeout_s: Annotated[float, Field(gt=0, le=60)] = (
        0.15  # Modbus request timeout, s (an RTU exchange at 19200 baud takes ~20 ms)
    )
    # consecutive failed polls that declare the drive link lost (the sweep's drive_link interlock)
    link_loss_polls: Annotated[int, Field(ge=1, le=100)] = 3
    comm_loss_timeout_s: Annotated[float, Field(gt=0, le=3_600)] = 1.0  # the drives' own COMM_LOSS_TIMEOUT
    ramp_rpm_per_s: Annotated[float, Field(gt=0, le=1e6)] = Field(
        600.0, description="drive ramp rate, for time estimates"
    )
    stop_timeout_s: Annotated[float, Field(gt=0, le=3_600)] = 30.0

    @field_validator("max_spin_rpm", "max_orbit_rpm")
    @classmethod
    def _commandable(cls, rpm: float) -> float:
        """A limit the drives can reach: at most drives.registers.MAX_COMMANDABLE_RPM."""
        top = R.MAX_COMMANDABLE_RPM
        if rpm > top:
            raise ValueError(
                f"{rpm:g} rpm is above the drive's maximum of {top:g} rpm (its MAX_SPEED: a larger REF is "
                "clamped, docs/protocols/drive-modbus.md); a faster speed would be refused when commanded"
            )
        return rpm

    @field_validator("comm_loss_timeout_s")
    @classmethod
    def _watchdog_on(cls, seconds: float) -> float:
        """A watchdog the drives hold as one: at least one count of COMM_LOSS_TIMEOUT (0 turns it off)."""
        if R.counts(seconds, R.TIME_UNIT) < 1:
            raise ValueError(
                f"{seconds:g} s is 0 counts of the drives' COMM_LOSS_TIMEOUT ({R.TIME_UNIT:g} s each), which "
                f"turns their comm-loss watchdog off; give at least {R.TIME_UNIT:g} s"
            )
        return seconds

    @property
    def link_loss_time_s(self) -> float:
        """Longest time from the last answer to a declared link loss (s)."""
        return self.link_loss_polls * (self.poll_interval_s + self.timeout_s)

    @property
    def watchdog_s(self) -> float:
        """comm_loss_timeout_s as the drives hold it: whole counts of COMM_LOSS_TIMEOUT (s)."""
        return R.counts(self.comm_loss_timeout_s, R.TIME_UNIT) * R.TIME_UNIT

    @model_validator(mode="after")
    def _ratio_order(self):
        if self.min_ratio is not None and self.max_ratio is not None and self.min_ratio >= self.max_ratio:
            raise ValueError("min_ratio must be smaller than max_ratio")
        if self.spin_id == self.orbit_id:
            raise ValueError("spin_id and orbit_id must differ")
        t, wd = self.link_loss_time_s, self.watchdog_s
        what = (
            f"link_loss_polls {self.link_loss_polls} x (poll_interval_s {self.poll_interval_s:g} + "
            f"timeout_s {self.timeout_s:g}) = {t:.2f} s"
        )
        held = "" if math.isclose(wd, self.comm_loss_timeout_s) else f" (held by the drives as {wd:g} s)"
        if t >= wd:
            raise ValueError(
                f"{what} is not below comm_loss_timeout_s = {self.comm_loss_timeout_s:g} s{held}: the drives would "
                "stop on their own watchdog before the link loss is declared"
            )
        if t > LINK_LOSS_MARGIN * wd:
            close = (
                f"[drives] {what} is close to comm_loss_timeout_s = {self.comm_loss_timeout_s:g} s{held} "
                f"(keep it under {LINK_LOSS_MARGIN:g} x)"
            )
            warnings.warn(ConfigWarning(close, ("drives", "link_loss_polls")), stacklevel=2)
        return self
