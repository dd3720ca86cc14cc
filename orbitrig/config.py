"""Rig and test-matrix configuration (TOML files validated with pydantic).

Files use the units an operator reads (rpm, MPa, mm, um, s, percent); every
model exposes SI properties (rad/s, Pa, m) for the code inside. A bad file
raises :class:`orbitrig.errors.ConfigError` with one message per problem,
naming the file, the key path and what is allowed.
"""

from __future__ import annotations

import math
import re
import tomllib
import warnings
from pathlib import Path
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, PrivateAttr, ValidationError, field_validator, model_validator

from orbitrig.errors import ConfigError

RPM = 2.0 * math.pi / 60.0  # rad/s per rpm
MPA = 1.0e6  # Pa per MPa

CHANNEL_NAMES = ("fx_piezo", "fy_piezo", "fx_strain", "fy_strain", "x_a", "y_a", "x_b", "y_b")
LMS = ("piezo", "strain")
MODELS = ("kc7", "kc8", "kcd11", "kcd12")
FREQ_DEP = re.compile(r"^(none|power:auto|power:[1-9]\d*|power:[1-9]\d*,[1-9]\d*,[1-9]\d*|poly:[1-9]\d*)$")

_REPO_CONFIG = Path(__file__).resolve().parent.parent / "config"


def default_rig_path() -> Path:
    return _REPO_CONFIG / "rig.toml"


def default_matrix_path(name: str = "demo") -> Path:
    return _REPO_CONFIG / "matrices" / f"{name}.toml"


def matrix_file(arg: str | Path, folder: Path | None = None) -> Path:
    """A test matrix given as a file, or as a bare name from ``folder`` (default:
    config/matrices/ of the source tree), as MQTT's `start` names one.

    Raises ConfigError naming the available matrices if ``arg`` is neither."""
    path = Path(arg)
    if path.is_file() or path.suffix == ".toml" or len(path.parts) != 1:
        return path  # a file (load_matrix names it if it cannot be read)
    folder = folder or default_matrix_path().parent
    named = folder / f"{arg}.toml"
    if named.is_file():
        return named
    names = sorted(p.stem for p in folder.glob("*.toml"))
    raise ConfigError(str(arg), [f"no such file, and no matrix of that name in {folder} "
                                 f"(available: {', '.join(names) or 'none'})"])  # fmt: skip


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


Pos = Annotated[float, Field(gt=0)]
NonNeg = Annotated[float, Field(ge=0)]


# ---------------------------------------------------------------- rig.toml
class Transports(_Model):
    adc_url: str = "socket://127.0.0.1:5000"
    adc_mode: Literal["sequential", "simultaneous"] = "sequential"
    modbus_url: str = "tcp://127.0.0.1:5020"
    can_channel: str = "can0"
    # python-can interface names: socketcan on a Linux rig, serial/slcan for USB
    # adapters, virtual for in-process tests
    can_interface: Literal["socketcan", "serial", "slcan", "pcan", "kvaser", "ixxat",
                           "vector", "socketcand", "virtual"] = "socketcan"
    can_bitrate: Annotated[int, Field(gt=0)] = 500_000
    can_node_id: Annotated[int, Field(ge=1, le=127)] = 1


class Channel(_Model):
    index: Annotated[int, Field(ge=0, le=63)]
    name: Literal[CHANNEL_NAMES]  # type: ignore[valid-type]
    quantity: str = ""
    unit: Literal["N", "m"]
    gain: float = Field(description="engineering unit per count")
    offset: float = 0.0

    @model_validator(mode="after")
    def _gain_nonzero(self):
        if self.gain == 0:
            raise ValueError("gain must be non-zero")
        return self


class Bearing(_Model):
    radius_mm: Pos = 30.0
    clearance_um: Pos = 60.0

    @property
    def clearance(self) -> float:
        """Radial clearance c (m)."""
        return self.clearance_um * 1e-6


LINK_LOSS_MARGIN = 0.8  # [drives] link_loss_time_s above this share of comm_loss_timeout_s warns


class Drives(_Model):
    max_spin_rpm: Pos = 2500.0
    max_orbit_rpm: Pos = 2500.0
    min_ratio: Annotated[float, Field(ge=0)] | None = None
    max_ratio: Pos | None = None
    spin_id: Annotated[int, Field(ge=1, le=247)] = 1
    orbit_id: Annotated[int, Field(ge=1, le=247)] = 2
    poll_interval_s: Pos = 0.1
    timeout_s: Pos = 0.15  # Modbus request timeout, s (an RTU exchange at 19200 baud takes ~20 ms)
    # consecutive failed polls that declare the drive link lost (the sweep's drive_link interlock)
    link_loss_polls: Annotated[int, Field(ge=1, le=100)] = 3
    comm_loss_timeout_s: Pos = 1.0  # the drives' own COMM_LOSS_TIMEOUT (spec default 1 s)
    ramp_rpm_per_s: Pos = Field(600.0, description="drive ramp rate, for time estimates")
    stop_timeout_s: Pos = 30.0

    @property
    def link_loss_time_s(self) -> float:
        """Longest time from the last answer to a declared link loss (s)."""
        return self.link_loss_polls * (self.poll_interval_s + self.timeout_s)

    @model_validator(mode="after")
    def _ratio_order(self):
        if self.min_ratio is not None and self.max_ratio is not None and self.min_ratio >= self.max_ratio:
            raise ValueError("min_ratio must be smaller than max_ratio")
        if self.spin_id == self.orbit_id:
            raise ValueError("spin_id and orbit_id must differ")
        t, wd = self.link_loss_time_s, self.comm_loss_timeout_s
        what = (f"link_loss_polls {self.link_loss_polls} x (poll_interval_s {self.poll_interval_s:g} + "
                f"timeout_s {self.timeout_s:g}) = {t:.2f} s")
        if t >= wd:
            raise ValueError(f"{what} is not below comm_loss_timeout_s = {wd:g} s: the drives would "
                             "stop on their own watchdog before the link loss is declared")
        if t > LINK_LOSS_MARGIN * wd:
            warnings.warn(f"[drives] {what} is close to comm_loss_timeout_s = {wd:g} s "
                          f"(keep it under {LINK_LOSS_MARGIN:g} x)", UserWarning, stacklevel=2)
        return self


class Averaging(_Model):
    revolutions: Annotated[int, Field(ge=2, le=10_000)] = 50
    timeout_factor: Annotated[float, Field(ge=1.2)] = 3.0
    timeout_margin_s: NonNeg = 2.0
    retries: Annotated[int, Field(ge=0, le=10)] = 1


class Settle(_Model):
    hold_s: NonNeg = 2.0
    timeout_s: Pos = 120.0


class Verify(_Model):
    orbit_radius_tol_pct: Pos = 15.0
    static_eccentricity_tol: Pos = 0.05
    recess_pressure_tol_pct: Pos = 10.0
    pressure_ratio_tol: Pos = 0.05


class Interlocks(_Model):
    supply_pressure_min_mpa: NonNeg = 0.2
    supply_pressure_max_mpa: Pos = 8.0
    check_supply_pressure: bool = True
    check_can_heartbeat: bool = True
    suspend_timeout_s: Pos = 300.0

    @model_validator(mode="after")
    def _band(self):
        if self.supply_pressure_min_mpa >= self.supply_pressure_max_mpa:
            raise ValueError("supply_pressure_min_mpa must be smaller than supply_pressure_max_mpa")
        return self


class Estimates(_Model):
    manual_setting_s: NonNeg = 120.0
    verify_s: NonNeg = 1.0
    identify_s: NonNeg = 0.2
    store_s: NonNeg = 0.05


class RigConfig(_Model):
    name: str = "rig"
    transports: Transports = Transports()
    channels: list[Channel]
    bearing: Bearing = Bearing()
    drives: Drives = Drives()
    averaging: Averaging = Averaging()
    settle: Settle = Settle()
    verify: Verify = Verify()
    interlocks: Interlocks = Interlocks()
    estimates: Estimates = Estimates()

    _file: str = PrivateAttr("<rig config>")
    _text: str = PrivateAttr("")

    @model_validator(mode="after")
    def _channel_map(self):
        problems = []
        names = [c.name for c in self.channels]
        missing = [n for n in CHANNEL_NAMES if n not in names]
        if missing:
            problems.append(f"missing channels {missing}; every one of {list(CHANNEL_NAMES)} is required")
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            problems.append(f"channel names used twice: {dup}")
        idx = sorted(c.index for c in self.channels)
        if idx != list(range(len(idx))):
            problems.append(f"channel indices must be 0..{len(idx) - 1} each once, got {idx}")
        elif self.transports.adc_mode == "sequential" and 360 % len(idx):
            # docs/protocols/adc-frames.md: in sequential mode slot s converts channel s mod C
            problems.append(f"in sequential mode the number of channels ({len(idx)}) must divide 360")
        for c in self.channels:
            want = "N" if c.name.startswith("f") else "m"
            if c.unit != want:
                problems.append(f"channel {c.name} must have unit '{want}'")
        if problems:
            raise ValueError("; ".join(problems))
        return self

    # -- derived, SI
    @property
    def file(self) -> str:
        return self._file

    @property
    def text(self) -> str:
        return self._text

    @property
    def ordered_channels(self) -> list[Channel]:
        return sorted(self.channels, key=lambda c: c.index)

    @property
    def channel_index(self) -> dict[str, int]:
        return {c.name: c.index for c in self.channels}

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


# ----------------------------------------------------- matrices/*.toml
class Operating(_Model):
    spin_rpm: Annotated[list[Pos], Field(min_length=1)]
    recess_pressure_mpa: Annotated[list[Pos], Field(min_length=1)]
    pressure_ratio: Annotated[list[Annotated[float, Field(gt=0, lt=1)]], Field(min_length=1)]
    static_eccentricity: Annotated[list[Annotated[float, Field(ge=0, lt=1)]], Field(min_length=1)]
    dynamic_eccentricity: Annotated[list[Annotated[float, Field(gt=0, lt=1)]], Field(min_length=1)]


class Orbit(_Model):
    """Orbit frequencies as ratios Omega/omega: either `ratios` or start/stop/count."""

    ratios: list[Pos] | None = None
    ratio_start: Pos | None = None
    ratio_stop: Pos | None = None
    count: Annotated[int, Field(ge=1, le=100)] | None = None
    directions: Annotated[list[Literal["forward", "backward"]], Field(min_length=1)] = ["forward", "backward"]

    @model_validator(mode="after")
    def _one_spec(self):
        rng = (self.ratio_start, self.ratio_stop, self.count)
        problems = []  # every problem of the table, not only the first
        if self.ratios is not None and any(v is not None for v in rng):
            problems.append("give either 'ratios' or 'ratio_start', 'ratio_stop', 'count', not both")
        if self.ratios is None and any(v is None for v in rng):
            problems.append("give 'ratios' (a list) or all of 'ratio_start', 'ratio_stop', 'count'")
        if self.ratios is not None and len(set(self.ratios)) != len(self.ratios):
            problems.append("'ratios' has repeated values")
        if len(set(self.directions)) != len(self.directions):
            problems.append("'directions' has repeated values")
        if (self.count is not None and self.count > 1 and None not in rng
                and self.ratio_start >= self.ratio_stop):
            problems.append("ratio_start must be smaller than ratio_stop")
        if problems:
            raise ValueError("; ".join(problems))
        return self

    @property
    def ratio_list(self) -> list[float]:
        """Orbit ratios |Omega|/omega, ascending."""
        if self.ratios is not None:
            return sorted(self.ratios)
        if self.count == 1:
            return [self.ratio_start]
        step = (self.ratio_stop - self.ratio_start) / (self.count - 1)
        return [round(self.ratio_start + k * step, 12) for k in range(self.count)]


class ModelSpec(_Model):
    model: Literal[MODELS]  # type: ignore[valid-type]
    freq_dep: str = "none"
    method: Literal["ols", "wls", "tls", "iv"] = "ols"

    @field_validator("freq_dep")
    @classmethod
    def _freq_dep(cls, v: str) -> str:
        from reduction.errors import ReductionError
        from reduction.models import MAX_ORDER, parse_freq_dep

        allowed = f"allowed: none, power:M, power:m,n,p, power:auto, poly:R (integers 1..{MAX_ORDER})"
        if not FREQ_DEP.fullmatch(v):
            raise ValueError(allowed)
        try:
            parse_freq_dep(v)  # the identification's own limits, so a run never meets them first
        except ReductionError:
            raise ValueError(allowed) from None
        return v

    @property
    def key(self) -> str:
        """Storage name: model, freq-dep and method (two methods of one model must not collide)."""
        return f"{self.model}__{self.freq_dep.replace(':', '_').replace(',', '_')}__{self.method}"


class MatrixConfig(_Model):
    name: str
    description: str = ""
    operating: Operating
    orbit: Orbit
    models: Annotated[list[ModelSpec], Field(min_length=1)]
    revolutions: Annotated[int, Field(ge=2, le=10_000)] | None = None
    settle_hold_s: NonNeg | None = None

    _file: str = PrivateAttr("<matrix>")
    _text: str = PrivateAttr("")

    @property
    def file(self) -> str:
        return self._file

    @property
    def text(self) -> str:
        return self._text


# ------------------------------------------------------------ loading
def _allowed_keys(model: type[BaseModel], loc: tuple) -> list[str] | None:
    """Field names of the model that holds the key at `loc` (for unknown-key messages)."""
    cls: object = model
    for part in loc[:-1]:
        if isinstance(part, int):
            continue
        if not (isinstance(cls, type) and issubclass(cls, BaseModel)) or part not in cls.model_fields:
            return None
        ann = cls.model_fields[part].annotation
        cls = _model_in(ann)
    if isinstance(cls, type) and issubclass(cls, BaseModel):
        return list(cls.model_fields)
    return None


def _model_in(ann) -> object:
    if isinstance(ann, type) and issubclass(ann, BaseModel):
        return ann
    for arg in getattr(ann, "__args__", ()) or ():
        found = _model_in(arg)
        if found is not None:
            return found
    return None


def _key_path(loc: tuple) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        elif not str(part).startswith(_LOC_SKIP):
            out += ("." if out else "") + str(part)
    return out or "(top level)"


_LOC_SKIP = ("function-", "literal[", "list[", "float", "int")
_HEADER = re.compile(r"^\s*(\[\[?)\s*([^\]]+?)\s*\]\]?\s*(#.*)?$")
_KEY = re.compile(r"^\s*([A-Za-z0-9_\-\"']+)\s*=")


def _line_of(text: str, loc: tuple) -> int | None:
    """1-based line of the key (or table header) at a pydantic location, None if not found."""
    want = tuple(p for p in loc if isinstance(p, int) or not str(p).startswith(_LOC_SKIP))
    if not want or not text:
        return None
    best, best_len = None, 0
    table: tuple = ()
    counts: dict[tuple, int] = {}
    for n, line in enumerate(text.splitlines(), 1):
        m = _HEADER.match(line)
        if m:
            path = tuple(part.strip().strip('"') for part in m.group(2).split("."))
            if m.group(1) == "[[":
                i = counts.get(path, 0)
                counts[path] = i + 1
                path = path + (i,)
            table, here = path, path
        else:
            k = _KEY.match(line)
            if not k:
                continue
            here = table + (k.group(1).strip("\"'"),)
        if len(here) > best_len and want[: len(here)] == here:
            best, best_len = n, len(here)
    return best


def _got(value) -> str:
    """A short rendering of the offending value (whole tables are not repeated)."""
    if isinstance(value, dict):
        return ""
    text = repr(value)
    return f" (got {text if len(text) <= 60 else text[:57] + '...'})"


def _problems(err: ValidationError, model: type[BaseModel], text: str = "") -> list[str]:
    out = []
    for e in err.errors(include_url=False):
        loc = tuple(e["loc"])
        key = _key_path(loc)
        line = _line_of(text, loc)
        where = f"line {line}: " if line else ""
        if e["type"] == "extra_forbidden":
            allowed = _allowed_keys(model, loc)
            hint = f"; allowed keys here: {', '.join(allowed)}" if allowed else ""
            out.append(f"{where}key '{key}': unknown key{hint}")
        elif e["type"] == "missing":
            out.append(f"{where}key '{key}': required key is missing")
        else:
            msg = e["msg"].removeprefix("Value error, ")
            out.append(f"{where}key '{key}': {msg}{_got(e.get('input'))}")
    return out


def _parse(text: str, file: str) -> dict:
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise ConfigError(file, [f"not valid TOML: {err}"]) from err


def _build(cls, data: dict, file: str, text: str):
    try:
        obj = cls.model_validate(data)
    except ValidationError as err:
        raise ConfigError(file, _problems(err, cls, text)) from err
    obj._file = file
    obj._text = text
    return obj


def _read(path: Path | str) -> tuple[str, str]:
    path = Path(path)
    try:
        return path.read_text(encoding="utf-8"), str(path)
    except OSError as err:
        raise ConfigError(str(path), [f"cannot read the file: {err.strerror or err}"]) from err


def _read_default(path: Path | str | None, default: Path, option: str) -> tuple[str, str]:
    if path is not None or default.is_file():
        return _read(path or default)
    raise ConfigError(str(default), [f"the default file is not there (orbitrig installed without its source tree? "
                                     f"install with pip install -e): give {option} FILE"])  # fmt: skip


def load_rig(path: Path | str | None = None) -> RigConfig:
    text, file = _read_default(path, default_rig_path(), "--config")
    return rig_from_text(text, file)


def rig_from_text(text: str, file: str = "<rig config>") -> RigConfig:
    return _build(RigConfig, _parse(text, file), file, text)


def load_matrix(path: Path | str | None = None) -> MatrixConfig:
    text, file = _read_default(path, default_matrix_path(), "--matrix")
    return matrix_from_text(text, file)


def matrix_from_text(text: str, file: str = "<matrix>") -> MatrixConfig:
    return _build(MatrixConfig, _parse(text, file), file, text)


def check_matrix_against_rig(matrix: MatrixConfig, rig: RigConfig) -> None:
    """Problems a matrix has only on this rig (drive limits), all in one ConfigError."""
    problems = []
    d = rig.drives
    text = getattr(matrix, "_text", "") or ""
    spin_at = _line_of(text, ("operating", "spin_rpm"))
    ratio_at = _line_of(text, ("orbit", "ratios")) or _line_of(text, ("orbit", "ratio_stop")) or _line_of(text, ("orbit",))
    at_spin = f"line {spin_at}: " if spin_at else ""
    at_ratio = f"line {ratio_at}: " if ratio_at else ""
    for rpm in matrix.operating.spin_rpm:
        if rpm > d.max_spin_rpm:
            problems.append(
                f"{at_spin}key 'operating.spin_rpm': {rpm:g} rpm exceeds the rig's drives.max_spin_rpm = {d.max_spin_rpm:g}"
            )
        top = max(matrix.orbit.ratio_list) * rpm
        if top > d.max_orbit_rpm:
            problems.append(
                f"{at_ratio}key 'orbit': ratio {max(matrix.orbit.ratio_list):g} at {rpm:g} rpm gives {top:g} rpm orbit, "
                f"above the rig's drives.max_orbit_rpm = {d.max_orbit_rpm:g}"
            )
    lo, hi = min(matrix.orbit.ratio_list), max(matrix.orbit.ratio_list)
    if d.min_ratio is not None and lo < d.min_ratio:
        problems.append(f"{at_ratio}key 'orbit': ratio {lo:g} is below the rig's drives.min_ratio = {d.min_ratio:g}")
    if d.max_ratio is not None and hi > d.max_ratio:
        problems.append(f"{at_ratio}key 'orbit': ratio {hi:g} is above the rig's drives.max_ratio = {d.max_ratio:g}")
    if problems:
        raise ConfigError(matrix.file, problems)
