"""Rig and test-matrix configuration (TOML files validated with pydantic).

Files use the units an operator reads (rpm, MPa, mm, um, s, percent); every
model exposes SI properties (rad/s, Pa, m) for the code inside. Every number
must be a TOML number (a count an integer, a switch true or false: nothing is
converted from text), finite and within its range. A bad file raises
:class:`orbitrig.errors.ConfigError` with one message per problem, naming the
file, the line, the key path and what is allowed; so does a file that is not
UTF-8 text.

The models live in ``rig`` (its [drives] section in ``drives_section``), ``calibration``, ``records`` (calibration records) and ``matrix``, the field types in ``fields``, the
error wording in ``messages``, a matrix's checks against the rig in ``plan_checks``, the drives' link a refused
rig.toml still gives in ``drives_link``, a file read and validated in ``reading``; everything is importable
from here. An active calibration record measured on another rig than rig.toml's is refused when the rig
configuration is loaded (``active_record``: ``check_record_rig``); so is a rig.toml without a key of the rig's
hardware (``hardware``: bearing, channel offsets, transports, drive limits and ids, supply band).
"""

from __future__ import annotations

from pathlib import Path

from orbitrig.config.calibration import CalibrationUncertainty, ChannelUncertainty  # noqa: F401
from orbitrig.config.fields import (  # noqa: F401 - the package's public names
    CHANNEL_NAMES,
    FREQ_DEP,
    LMS,
    MODELS,
    MPA,
    RPM,
    ChannelName,
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
from orbitrig.config.hardware import CHANNEL_KEYS, HARDWARE_KEYS, missing_hardware  # noqa: F401
from orbitrig.config.home import (
    HOME_ENV as HOME_ENV,
    MATRICES,
    RIG_FILE,
    config_home,
    known_names,
    named_file,
    search_folders,
    shipped_config as shipped_config,
    writable_home as writable_home,
)
from orbitrig.config.lab import SHIPPED_RIG_ID, write_lab  # noqa: F401
from orbitrig.config.sequential import SequentialDesign, band_candidates, candidate_problems  # noqa: F401
from orbitrig.config.resume import MAY_CHANGE, matrix_differences, matrix_differs, resume_differences  # noqa: F401
from orbitrig.config.matrix import (  # noqa: F401
    MAX_REVOLUTIONS,
    MIN_RATIOS,
    MIN_REVOLUTIONS,
    MatrixAveraging,
    MatrixConfig,
    ModelSpec,
    Operating,
    Orbit,
    PointOrder,
)
from orbitrig.config.messages import ConfigWarning, key_line, problem_lines, bom_problem, reissue  # noqa: F401
from orbitrig.config.plan_checks import check_matrix_against_rig, orbit_hz, plan_warnings, warning_lines  # noqa: F401
from orbitrig.config.record_age import age_lines, age_warning, part_ages, validity  # noqa: F401
from orbitrig.config.records import (  # noqa: F401
    CalibrationRecord,
    ChannelDelay,
    LoadGains,
    ProbeGain,
    ProbeRunout,
    RecordStep,
    Reference,
    Runout,
)
from orbitrig.config.record_files import NAME as RECORD_NAME, NAME_RULE as RECORD_NAME_RULE  # noqa: F401
from orbitrig.config.record_files import name_problem as record_name_problem  # noqa: F401
from orbitrig.config.record_files import activate, folder_of, list_names, read_all, read_record  # noqa: F401
from orbitrig.config.record_files import record_from_text
from orbitrig.config.record_files import write_dated, write_record  # noqa: F401
from orbitrig.config.record_seal import (  # noqa: F401
    SealState,
    UnverifiableRecordWarning,
    check_seal,
    digest,
    seal_mark,
    seal_note,
    seal_state,
)
from orbitrig.config.record_setup import PROBE_CHANNELS, check_setup, identity, made_elsewhere  # noqa: F401
from orbitrig.config.drives_section import LINK_LOSS_MARGIN, Drives  # noqa: F401
from orbitrig.config.drives_link import DrivesLink, drives_link  # noqa: F401
from orbitrig.config.rig import (  # noqa: F401
    Averaging,
    Bearing,
    Channel,
    Estimates,
    Interlocks,
    RigConfig,
    Settle,
    Transports,
    Verify,
)
from orbitrig.config.reading import build_model, parse_toml, read_given_or_default, decode_text, read_text  # noqa: F401
from orbitrig.config.active_record import (  # noqa: F401
    read_active_record,
    check_on_the_rig,
    check_record_rig,
    other_scenario,
    record_folder,
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


def load_rig(path: Path | str | None = None, *, check_record: bool = True) -> RigConfig:
    """The rig configuration in ``path`` (rig_from_text), which must give every key of the rig's
    hardware (orbitrig.config.hardware); ``check_record=False``: its active record
    is not refused when measured on another rig or channel setup (`calibrate list` and `show`
    show the history whatever is active; nothing is measured or corrected with it)."""
    text, file = read_given_or_default(path, default_rig_path(), "--config")
    return rig_from_text(text, file, check_record=check_record, hardware=True)


def rig_from_text(
    text: str,
    file: str = "<rig config>",
    record_text: str | None = None,
    *,
    check_record: bool = True,
    hardware: bool = False,
) -> RigConfig:
    """The rig configuration with its active calibration record: ``record_text`` (a run's stored
    copy) or the file named by ``calibration_record`` in ``record_folder(file)``, refused when
    measured on another rig or channel setup (``check_record``). The record's ``[uncertainty]``
    replaces ``[calibration_uncertainty]``. ``hardware``: a key of the rig's hardware left out is
    refused (missing_hardware), with the file's other problems; else it is the paper's rig's."""
    data = parse_toml(text, file)
    missing = missing_hardware(data, text) if hardware else []
    try:
        rig = build_model(RigConfig, data, file, text)
    except ConfigError as err:
        raise ConfigError(file, missing + err.problems) from None
    if missing:
        raise ConfigError(file, missing)
    name = rig.calibration_record
    if name is None:
        return rig
    if record_text is None:  # the folder's active record: it must be this rig's
        record, record_text = read_active_record(file, text, name)
        if check_record:
            check_record_rig(rig, record, record_text)
    else:
        record = record_from_text(record_text, f"{file}: calibration record {name}")
    return rig.with_active_record(record, record_text)


def load_matrix(path: Path | str | None = None) -> MatrixConfig:
    text, file = read_given_or_default(path, default_matrix_path(), "--matrix")
    return matrix_from_text(text, file)


def matrix_from_text(text: str, file: str = "<matrix>") -> MatrixConfig:
    data = parse_toml(text, file)
    problems = apply_design(data, file)  # [orbit] design = "NAME": the designed ratios
    if problems:
        at = key_line(text, ("orbit", "design"))
        raise ConfigError(file, [f"line {at}: {p}" if at else p for p in problems])
    return build_model(MatrixConfig, data, file, text)
