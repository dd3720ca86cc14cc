"""Rig and test-matrix configuration (TOML files validated with pydantic).

Files use the units an operator reads (rpm, MPa, mm, um, s, percent); every
model exposes SI properties (rad/s, Pa, m) for the code inside. Every number
must be a TOML number (a count an integer, a switch true or false: nothing is
converted from text), finite and within its range. A bad file raises
:class:`orbitrig.errors.ConfigError` with one message per problem, naming the
file, the line, the key path and what is allowed; so does a file that is not
UTF-8 text.

The models live in ``rig``, ``calibration``, ``records`` (calibration records) and ``matrix``, the field types in ``fields``, the
error wording in ``messages``; everything is importable from here.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

from pydantic import ValidationError

from orbitrig.config.calibration import CalibrationUncertainty, ChannelUncertainty  # noqa: F401
from orbitrig.config.fields import (  # noqa: F401 - the package's public names
    CHANNEL_NAMES,
    FREQ_DEP,
    LMS,
    MODELS,
    MPA,
    RPM,
    DeviceId,
    Mpa,
    NonNeg,
    Pos,
    Ratio,
    Rpm,
    Seconds,
    Wait,
)
from orbitrig.config.designs import apply_design
from orbitrig.config.home import (
    HOME_ENV,
    MATRICES,
    RIG_FILE,
    config_home,
    known_names,
    named_file,
    search_folders,
    shipped_config,
)
from orbitrig.config.lab import write_lab  # noqa: F401
from orbitrig.config.sequential import SequentialDesign, band_candidates, candidate_problems  # noqa: F401
from orbitrig.config.resume import MAY_CHANGE, resume_differences  # noqa: F401
from orbitrig.config.matrix import MatrixAveraging, MatrixConfig, ModelSpec, Operating, Orbit, PointOrder  # noqa: F401
from orbitrig.config.messages import _line_of, _problems
from orbitrig.config.records import (  # noqa: F401
    CalibrationRecord,
    ChannelDelay,
    LoadGains,
    ProbeGain,
    ProbeRunout,
    RecordStep,
    Reference,
    Runout,
    activate,
    digest,
    folder_of,
    list_names,
    read_record,
    record_from_text,
    write_record,
)
from orbitrig.config.rig import (  # noqa: F401
    LINK_LOSS_MARGIN,
    Averaging,
    Bearing,
    Channel,
    Drives,
    Estimates,
    Interlocks,
    RigConfig,
    Settle,
    Transports,
    Verify,
)
from orbitrig.errors import ConfigError


def default_rig_path() -> Path:
    """rig.toml of the lab configuration (orbitrig.config.home: $ORBITRIG_HOME, the current
    directory, the shipped defaults)."""
    return config_home() / RIG_FILE


def default_matrix_path(name: str = "demo", rig_path: Path | str | None = None) -> Path:
    """The matrix NAME: from the lab's matrices/ (the folder of ``rig_path``), else shipped."""
    return named_file(MATRICES, name, rig_path)


def matrix_file(arg: str | Path, folder: Path | None = None, rig_path: Path | str | None = None) -> Path:
    """A test matrix given as a file, or as a bare name from ``folder`` (default: the lab's
    matrices/, then the shipped ones; see orbitrig.config.home), as MQTT's `start` names one.

    Raises ConfigError naming the available matrices if ``arg`` is neither."""
    path = Path(arg)
    if path.is_file() or path.suffix == ".toml" or len(path.parts) != 1:
        return path  # a file (load_matrix names it if it cannot be read)
    named = folder / f"{arg}.toml" if folder else default_matrix_path(str(arg), rig_path)
    if named.is_file():
        return named
    names = sorted(p.stem for p in folder.glob("*.toml")) if folder else known_names(MATRICES, rig_path)
    where = folder or " or ".join(str(f) for f in search_folders(MATRICES, rig_path))
    raise ConfigError(
        str(arg), [f"no such file, and no matrix of that name in {where} (available: {', '.join(names) or 'none'})"]
    )


def _parse(text: str, file: str) -> dict:
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise ConfigError(file, [f"not valid TOML: {err}"]) from err
    except RecursionError:
        raise ConfigError(file, ["not valid TOML: arrays or tables nested too deeply"]) from None


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
        data = path.read_bytes()
    except OSError as err:
        raise ConfigError(str(path), [f"cannot read the file: {err.strerror or err}"]) from err
    return decode_text(data, str(path)), str(path)


def decode_text(data: bytes, file: str) -> str:
    """UTF-8 text of a configuration file, or ConfigError naming the line and byte."""
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as err:
        line = data.count(b"\n", 0, err.start) + 1
        raise ConfigError(
            file, [f"line {line}: not UTF-8 text ({err.reason} at byte {err.start}); save the file as UTF-8"]
        ) from None


def _read_default(path: Path | str | None, default: Path, option: str) -> tuple[str, str]:
    if path is not None or default.is_file():
        return _read(path or default)
    raise ConfigError(
        str(default),
        [
            f"the default file is not there: give {option} FILE, set {HOME_ENV} to a "
            "folder made by `orbitrig init DIR`, or run in such a folder"
        ],
    )


def load_rig(path: Path | str | None = None) -> RigConfig:
    text, file = _read_default(path, default_rig_path(), "--config")
    return rig_from_text(text, file)


def rig_from_text(text: str, file: str = "<rig config>", record_text: str | None = None) -> RigConfig:
    """The rig configuration with its active calibration record: ``record_text`` (a run's stored
    copy) or the file named by ``calibration_record`` in ``record_folder(file)``. The record's
    ``[uncertainty]`` replaces ``[calibration_uncertainty]``."""
    rig = _build(RigConfig, _parse(text, file), file, text)
    name = rig.calibration_record
    if name is None:
        return rig
    if record_text is None:
        record, record_text = _active_record(file, text, name)
    else:
        record = record_from_text(record_text, f"{file}: calibration record {name}")
    out = rig.model_copy(update={"calibration_uncertainty": record.uncertainty})
    out._file, out._text, out._record, out._record_text = file, text, record, record_text
    return out


def record_folder(file: str) -> Path:
    """The calibration records' folder of the rig configuration ``file``: calibration/ beside it,
    or the shipped defaults' when there is no such folder (a rig.toml copied elsewhere alone, or
    text that is not from a file)."""
    beside = folder_of(file) if Path(file).is_file() else None
    return beside if beside is not None and beside.is_dir() else shipped_config() / "calibration"


def _active_record(file: str, text: str, name: str) -> tuple[CalibrationRecord, str]:
    """(record, its text) of the active record ``name``; a missing one is a ConfigError naming the
    rig configuration, the line of ``calibration_record`` and the records of the folder searched."""
    folder = record_folder(file)
    if not (folder / f"{name}.toml").is_file():
        at = _line_of(text, ("calibration_record",))
        known = ", ".join(list_names(folder)) or "none"
        raise ConfigError(
            file,
            [
                f"{f'line {at}: ' if at else ''}key 'calibration_record': no calibration record {name!r} "
                f"in {folder} (records there: {known})"
            ],
        )
    return read_record(folder, name)


def load_matrix(path: Path | str | None = None) -> MatrixConfig:
    text, file = _read_default(path, default_matrix_path(), "--matrix")
    return matrix_from_text(text, file)


def matrix_from_text(text: str, file: str = "<matrix>") -> MatrixConfig:
    data = _parse(text, file)
    problems = apply_design(data, file)  # [orbit] design = "NAME": the designed ratios
    if problems:
        at = _line_of(text, ("orbit", "design"))
        raise ConfigError(file, [f"line {at}: {p}" if at else p for p in problems])
    return _build(MatrixConfig, data, file, text)


def check_matrix_against_rig(matrix: MatrixConfig, rig: RigConfig) -> None:
    """Problems a matrix has only on this rig (drive limits), all in one ConfigError."""
    problems = []
    d = rig.drives
    text = matrix.text
    spin_at = _line_of(text, ("operating", "spin_rpm"))
    ratio_at = (
        _line_of(text, ("orbit", "ratios")) or _line_of(text, ("orbit", "ratio_stop")) or _line_of(text, ("orbit",))
    )
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
    problems += _sequential_problems(matrix, rig)
    if problems:
        raise ConfigError(matrix.file, problems)


def _sequential_problems(matrix: MatrixConfig, rig: RigConfig) -> list[str]:
    """A sequential matrix's candidates and reference list against the drive limits (with the line)."""
    at = _line_of(matrix.text, ("sequential",))
    return [f"line {at}: {p}" if at else p for p in candidate_problems(matrix, rig)]
