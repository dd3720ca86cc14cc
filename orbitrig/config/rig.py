"""The rig configuration (rig.toml): transports, channels, bearing, drives,
averaging, settling, verification, interlocks and estimates. Operator units in
the file (rpm, MPa, mm, um, s, percent); SI through the properties."""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Literal

from pydantic import Field, PrivateAttr, ValidationInfo, field_validator, model_validator

from daq.adc_mode import SLOTS_PER_REV, AdcMode
from drives.errors import DriveLinkError
from drives.link_url import parse_modbus_url
from orbitrig.config.calibration import CalibrationUncertainty
from orbitrig.config.drives_section import Drives
from orbitrig.config.fields import (
    BY_VALUE,
    CHANNEL_NAMES,
    RPM,
    Mpa,
    Pos,
    Seconds,
    Wait,
    FileConfig,
    ConfigModel,
)
from orbitrig.config.messages import KeyProblems
from orbitrig.config.record_files import NAME_PATTERN as RECORD_NAME_PATTERN
from orbitrig.config.record_setup import PROBE_CHANNELS
from rigunits import UM

if TYPE_CHECKING:
    from orbitrig.config.records import CalibrationRecord


class Transports(ConfigModel):
    adc_url: str = "socket://127.0.0.1:5000"
    adc_mode: Annotated[AdcMode, BY_VALUE] = AdcMode.SEQUENTIAL
    modbus_url: str = "tcp://127.0.0.1:5020"
    can_channel: str = "can0"
    # python-can interface names: socketcan on a Linux rig, serial/slcan for USB
    # adapters, virtual for in-process tests
    can_interface: Literal[
        "socketcan", "serial", "slcan", "pcan", "kvaser", "ixxat", "vector", "socketcand", "virtual"
    ] = "socketcan"
    can_bitrate: Annotated[int, Field(gt=0, le=10_000_000)] = 500_000
    can_node_id: Annotated[int, Field(ge=1, le=127)] = 1

    @field_validator("modbus_url")
    @classmethod
    def _modbus_address(cls, url: str) -> str:
        """A URL the drives' link can open (drives.link_url), refused here rather than when the drives are opened."""
        try:
            parse_modbus_url(url)
        except DriveLinkError as err:
            raise ValueError(err.reason) from None
        return url


#: physical calibration bounds per unit: (smallest |gain|, largest |gain|) per count of the
#: 16-bit A/D (full scale 32768 counts), largest |offset|, and whether the gain may be negative
#: (a load cell's sign is carried by its gain; a probe's axis is fixed by the rig's frame)
CHANNEL_BOUNDS = {"N": (1e-9, 1e3, 1e7, True), "m": (1e-15, 1e-4, 1.0, False)}


class Channel(ConfigModel):
    """One A/D channel: engineering value = gain * counts + offset (N or m)."""

    index: Annotated[int, Field(ge=0, le=63)]
    name: Literal[CHANNEL_NAMES]  # type: ignore[valid-type]
    quantity: str = ""
    unit: Literal["N", "m"]
    gain: float = Field(description="engineering unit per count")
    offset: float = 0.0
    serial: str = ""  # the sensor's serial number (recorded in every run)

    @field_validator("gain")
    @classmethod
    def _physical_gain(cls, gain: float, info: ValidationInfo) -> float:
        unit = info.data.get("unit")
        if unit not in CHANNEL_BOUNDS:
            return gain  # the unit's own error is reported
        low, high, _, signed = CHANNEL_BOUNDS[unit]
        if gain == 0:
            raise ValueError("gain must be non-zero")
        if gain < 0 and not signed:
            raise ValueError(f"gain {gain:g} {unit} per count: a displacement probe's gain must be positive")
        if not low <= abs(gain) <= high:
            raise ValueError(
                f"gain {gain:g} {unit} per count is not physical: |gain| between {low:g} and "
                f"{high:g} {unit} per count (full scale {low * 32768:.3g}..{high * 32768:.3g} {unit})"
            )
        return gain

    @field_validator("offset")
    @classmethod
    def _physical_offset(cls, offset: float, info: ValidationInfo) -> float:
        bound = CHANNEL_BOUNDS.get(info.data.get("unit", ""), (0, 0, float("inf"), True))[2]
        if abs(offset) > bound:
            raise ValueError(f"offset {offset:g} is not physical: |offset| at most {bound:g} {info.data['unit']}")
        return offset


class Bearing(ConfigModel):
    """The bearing's size; the lower bounds catch a value in metres (0.01905, 6e-05) in a mm or um field."""

    radius_mm: Annotated[float, Field(ge=1, le=10_000)] = 19.05  # the paper's bearing, D = 38.1 mm: recorded only
    clearance_um: Annotated[float, Field(ge=1, le=100_000)] = 60.0

    @property
    def clearance(self) -> float:
        """Radial clearance c (m)."""
        return self.clearance_um * UM


class Averaging(ConfigModel):
    revolutions: Annotated[int, Field(ge=2, le=10_000)] = 50
    timeout_factor: Annotated[float, Field(ge=1.2, le=1_000)] = 3.0
    timeout_margin_s: Annotated[float, Field(ge=0, le=3_600)] = 2.0
    retries: Annotated[int, Field(ge=0, le=10)] = 1
    orbit_speed_tol_pct: Annotated[float, Field(gt=0, le=50)] = 0.5

    @property
    def speed_tolerance(self) -> float:
        """``orbit_speed_tol_pct`` as a fraction (daq.averaging_rule.AveragingRule.speed_tolerance)."""
        return self.orbit_speed_tol_pct / 100.0


class Settle(ConfigModel):
    hold_s: Wait = 2.0
    timeout_s: Seconds = 120.0


class Verify(ConfigModel):
    orbit_radius_tol_pct: Annotated[float, Field(gt=0, le=100)] = 15.0
    static_eccentricity_tol: Annotated[float, Field(gt=0, le=1)] = 0.05
    recess_pressure_tol_pct: Annotated[float, Field(gt=0, le=100)] = 10.0
    pressure_ratio_tol: Annotated[float, Field(gt=0, le=1)] = 0.05


class Interlocks(ConfigModel):
    supply_pressure_min_mpa: Annotated[float, Field(ge=0, le=1_000)] = 0.2
    supply_pressure_max_mpa: Mpa = 8.0
    check_supply_pressure: bool = True
    check_can_heartbeat: bool = True
    suspend_timeout_s: Seconds = 300.0
    can_heartbeat_timeout_s: Seconds = 10.0  # wall s without the CAN node (or its data) before the run fails
    supply_lost_timeout_s: Seconds = 10.0  # wall s with the pump off or the supply too low before the run fails
    unanswered_pause_s: Seconds = 60.0  # wall s a pause nobody can answer lasts before the run stops

    @model_validator(mode="after")
    def _band(self):
        if self.supply_pressure_min_mpa >= self.supply_pressure_max_mpa:
            raise ValueError("supply_pressure_min_mpa must be smaller than supply_pressure_max_mpa")
        return self


class Estimates(ConfigModel):
    manual_setting_s: Wait = 120.0
    verify_s: Wait = 1.0
    identify_s: Wait = 0.2
    store_s: Wait = 0.05


class Changeover(ConfigModel):
    """Seconds the operator needs to change each manual variable and let it settle (the
    static eccentricity is set by thermal expansion: slow). A point after the first costs the
    sum over the variables that change; the plan orders the points to spend least."""

    orbit_radius_s: Wait = 120.0
    static_eccentricity_s: Wait = 120.0
    recess_pressure_s: Wait = 120.0
    pressure_ratio_s: Wait = 120.0

    def of(self) -> tuple[float, float, float, float]:
        """Seconds in the order of OperatingPoint.manual: orbit radius, static eccentricity,
        recess pressure, pressure ratio."""
        return (self.orbit_radius_s, self.static_eccentricity_s, self.recess_pressure_s, self.pressure_ratio_s)


class RigConfig(FileConfig):
    name: str = "rig"
    rig_id: str = ""  # the rig's identifier recorded in every run (default: name)
    # the active calibration record (calibration/NAME.toml beside this file); None: none
    calibration_record: Annotated[str, Field(pattern=RECORD_NAME_PATTERN)] | None = None
    transports: Transports = Transports()
    channels: list[Channel]
    bearing: Bearing = Bearing()
    drives: Drives = Drives()
    averaging: Averaging = Averaging()
    settle: Settle = Settle()
    verify: Verify = Verify()
    interlocks: Interlocks = Interlocks()
    estimates: Estimates = Estimates()
    # per manual variable, change + settle seconds; None: every change costs estimates.manual_setting_s
    changeover: Changeover | None = None
    # the active record's runout taken out of every block's probe phasors (docs/calibration.md)
    subtract_runout: bool = True
    # days a measurement of the active record stays valid: an older one is warned of (record_age); None: no limit
    calibration_valid_days: Pos | None = None
    # stated calibration uncertainty; None: not stated (no systematic budget)
    calibration_uncertainty: CalibrationUncertainty | None = None

    _file: str = PrivateAttr("<rig config>")
    _record: object = PrivateAttr(None)  # the active CalibrationRecord (orbitrig.config.records)
    _record_text: str = PrivateAttr("")

    @model_validator(mode="after")
    def _channel_map(self):
        """Every channel once, by name and by index 0..C-1, each with its quantity's unit; each
        problem at the key of the entry it concerns (KeyProblems: its line in the file)."""
        problems: list[tuple[tuple, str]] = []
        names = [c.name for c in self.channels]
        missing = [n for n in CHANNEL_NAMES if n not in names]
        if missing:
            problems.append(
                (("channels",), f"missing channels {missing}; every one of {list(CHANNEL_NAMES)} is required")
            )
        seen: dict[object, int] = {}
        for i, c in enumerate(self.channels):
            if c.name in seen:
                problems.append(
                    (("channels", i, "name"), f"channel {c.name} given twice (also channels[{seen[c.name]}])")
                )
            seen.setdefault(c.name, i)
        count, at, indexed = len(self.channels), {}, True
        for i, c in enumerate(self.channels):
            if not 0 <= c.index < count or c.index in at:
                indexed = False
                also = f" (also channels[{at[c.index]}])" if c.index in at else ""
                problems.append(
                    (("channels", i, "index"), f"index {c.index}{also}: indices must be 0..{count - 1}, each once")
                )
            at.setdefault(c.index, i)
        if indexed and self.transports.adc_mode is AdcMode.SEQUENTIAL and SLOTS_PER_REV % count:
            # docs/protocols/adc-frames.md: in sequential mode slot s converts channel s mod C
            problems.append(
                (
                    ("transports", "adc_mode"),
                    f"in sequential mode the number of channels ({count}) must divide {SLOTS_PER_REV}",
                )
            )
        for i, c in enumerate(self.channels):
            want = "N" if c.name.startswith("f") else "m"
            if c.unit != want:
                problems.append((("channels", i, "unit"), f"channel {c.name} must have unit '{want}'"))
        if problems:
            raise KeyProblems(problems)
        return self

    # -- derived, SI
    @property
    def identity(self) -> str:
        """The rig's identifier as runs and calibration records carry it: rig_id, else name."""
        return self.rig_id or self.name

    @property
    def record(self):
        """The active CalibrationRecord, or None."""
        return self._record

    @property
    def record_text(self) -> str:
        """The active record's TOML text ("" without one)."""
        return self._record_text

    def with_active_record(self, record: CalibrationRecord, record_text: str) -> RigConfig:
        """A copy of this configuration (its file and text kept) carrying ``record``, the active
        calibration record whose TOML text is ``record_text``, and the uncertainty the record states."""
        out = self.model_copy(update={"calibration_uncertainty": record.uncertainty})
        out.remember_record(record, record_text)
        return out

    def remember_record(self, record: CalibrationRecord, record_text: str) -> None:
        """Keep ``record`` as the active calibration record, ``record_text`` its TOML text as read."""
        self._record, self._record_text = record, record_text

    @property
    def ordered_channels(self) -> list[Channel]:
        return sorted(self.channels, key=lambda c: c.index)

    @property
    def channel_index(self) -> dict[str, int]:
        return {c.name: c.index for c in self.channels}

    @property
    def probe_channels(self) -> tuple[int, ...]:
        """The four displacement probes' channel indices (PROBE_CHANNELS' order)."""
        index = self.channel_index
        return tuple(index[p] for p in PROBE_CHANNELS)

    @property
    def gains(self) -> list[float]:
        return [c.gain for c in self.ordered_channels]

    @property
    def offsets(self) -> list[float]:
        return [c.offset for c in self.ordered_channels]

    @property
    def max_spin(self) -> float:
        return self.drives.max_spin_rpm * RPM

    @property
    def max_orbit(self) -> float:
        return self.drives.max_orbit_rpm * RPM

    @property
    def ramp_rate(self) -> float:
        """Drive ramp rate (rad/s per s), for estimates."""
        return self.drives.ramp_rpm_per_s * RPM

    @property
    def block_overhead_s(self) -> float:
        """Seconds a block costs besides its revolutions: the settle hold and the store estimate
        (the per-block time of reduction.rig_time's estimates)."""
        return self.settle.hold_s + self.estimates.store_s
