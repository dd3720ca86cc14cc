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
rig.toml still gives in ``drives_link``; everything is importable from here.
An active calibration record measured on another rig than rig.toml's is refused when the rig
configuration is loaded (``check_record_rig``); so is a rig.toml without a key of the rig's
hardware (``hardware``: bearing, channel offsets, transports, drive limits and ids, supply band).
"""

from __future__ import annotations

import tomllib
import warnings
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
    HOME_ENV,
    MATRICES,
    RIG_FILE,
    config_home,
    known_names,
    named_file,
    search_folders,
    shipped_config,
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
from orbitrig.config.messages import ConfigWarning, _line_of, _problems, bom_problem, reissue  # noqa: F401
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
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            obj = cls.model_validate(data)
    except ValidationError as err:
        raise ConfigError(file, _problems(err, cls, text)) from err
    reissue(caught, file, text)  # at the line of the file they concern
    obj._file = file
    obj._text = text
    return obj


def read_text(path: Path | str) -> tuple[str, str]:
    """(UTF-8 text, path) of a configuration file, or ConfigError naming it."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as err:
        raise ConfigError(str(path), [f"cannot read the file: {err.strerror or err}"]) from err
    return decode_text(data, str(path)), str(path)


def decode_text(data: bytes, file: str) -> str:
    """UTF-8 text of a configuration file, or ConfigError naming the line and byte (or the byte
    order mark that TOML forbids)."""
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as err:
        line = data.count(b"\n", 0, err.start) + 1
        raise ConfigError(
            file, [f"line {line}: not UTF-8 text ({err.reason} at byte {err.start}); save the file as UTF-8"]
        ) from None
    bom = bom_problem(text)
    if bom is not None:
        raise ConfigError(file, [bom])
    return text


#: what to give instead of a file that is not there, by option
_WHAT_TO_GIVE = {
    "--config": "a rig.toml (`orbitrig init DIR` writes DIR/rig.toml to edit)",
    "--matrix": "a matrix TOML file or the name of one in the configuration's matrices/",
}


def _read_default(path: Path | str | None, default: Path, option: str) -> tuple[str, str]:
    if path is not None and (Path(path).is_dir() or not Path(path).exists()):
        found = "is a folder" if Path(path).is_dir() else "no such file"
        raise ConfigError(str(path), [f"{found}: give {option} {_WHAT_TO_GIVE[option]}"])
    if path is not None or default.is_file():
        return read_text(path or default)
    raise ConfigError(
        str(default),
        [
            f"the default file is not there: give {option} FILE, set {HOME_ENV} to a "
            "folder made by `orbitrig init DIR`, or run in such a folder"
        ],
    )


def load_rig(path: Path | str | None = None, *, check_record: bool = True) -> RigConfig:
    """The rig configuration in ``path`` (rig_from_text), which must give every key of the rig's
    hardware (orbitrig.config.hardware); ``check_record=False``: its active record
    is not refused when measured on another rig or channel setup (`calibrate list` and `show`
    show the history whatever is active; nothing is measured or corrected with it)."""
    text, file = _read_default(path, default_rig_path(), "--config")
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
    data = _parse(text, file)
    missing = missing_hardware(data, text) if hardware else []
    try:
        rig = _build(RigConfig, data, file, text)
    except ConfigError as err:
        raise ConfigError(file, missing + err.problems) from None
    if missing:
        raise ConfigError(file, missing)
    name = rig.calibration_record
    if name is None:
        return rig
    if record_text is None:  # the folder's active record: it must be this rig's
        record, record_text = _active_record(file, text, name)
        if check_record:
            check_record_rig(rig, record, record_text)
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


def _record_file(rig: RigConfig) -> Path:
    """The file of the rig configuration's active calibration record (record_folder's NAME.toml)."""
    return record_folder(rig.file) / f"{rig.calibration_record}.toml"


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


def check_record_rig(rig: RigConfig, record: CalibrationRecord, record_text: str) -> None:
    """A ConfigError naming the record file, its rig and rig.toml's when the active record was
    measured on another rig (orbitrig.config.record_setup.made_elsewhere), with the records of this
    rig; or with another channel setup (check_setup); or edited after its step wrote it (check_seal)."""
    path = _record_file(rig)
    check_seal(record, record_text, path)  # an edited record's rig and channels are not what was measured
    if not made_elsewhere(record, rig.name, rig.rig_id):
        check_setup(rig, record, record_text, path)  # the channels' serials and gains it was measured with
        return
    folder, ours = path.parent, []
    at, key_at = _line_of(record_text, ("rig",)), _line_of(rig.text, ("calibration_record",))
    for other in list_names(folder):
        try:
            rec, _ = read_record(folder, other)
        except ConfigError:
            continue
        if not made_elsewhere(rec, rig.name, rig.rig_id):
            ours.append(other)
    ident = f"name {rig.name!r}" + (f", rig_id {rig.rig_id!r}" if rig.rig_id else "")
    raise ConfigError(
        str(path),
        [
            f"{f'line {at}: ' if at else ''}key 'rig': this {record.step} record was measured on rig "
            f"{record.rig!r}, not on the rig of {rig.file} ({ident}), whose calibration_record"
            f"{f' (line {key_at})' if key_at else ''} makes it the active one: its corrections belong to "
            f"another rig. Set calibration_record to a record of this rig (in {folder}: "
            f"{', '.join(ours) or 'none'}), or remove the key and calibrate this rig "
            "(`orbitrig calibrate loads|runout|delay|probes`)"
        ],
    )


def check_on_the_rig(rig: RigConfig, nothing: str = "") -> None:
    """A ConfigError, before a run or step on the rig itself, naming the active record's file and
    its ``simulator`` line when the record was measured on the simulator: its runout, lags and
    gains are the simulator's (a --sim run or step takes it). ``nothing``: what was not made."""
    record = rig.record
    if record is None or not record.simulator:
        return
    at = _line_of(rig.record_text, ("simulator",))
    raise ConfigError(
        str(_record_file(rig)),
        [
            f"{f'line {at}: ' if at else ''}key 'simulator': this {record.step} record was measured on the "
            f"simulator ({record.simulator}), not on the rig: its corrections are the simulator's. Set "
            f"calibration_record in {rig.file} to a record measured on the rig, or remove the key and "
            "calibrate the rig (`orbitrig calibrate loads|runout|delay|probes` without --sim)"
            + (f"; {nothing}" if nothing else "")
        ],
    )


def other_scenario(rig: RigConfig, scenario: str, text: str) -> str | None:
    """A warning, for a run on the simulator's `scenario` (its file, as a run records it, and its
    TOML `text`), when the active record was measured on another scenario: its runout and lags are
    that scenario's, and they correct this one's blocks. Not a refusal: a --sim run (CI, training)
    still runs. Compared by content (the record's ``simulator_sha256`` against the SHA-256 of
    `text`: a copy of the scenario elsewhere is the same, the file edited since is not); a record
    written before that key by the resolved path of ``simulator``. None if the record was measured
    on this scenario, or typed in (an ``initial`` record); a record measured on the real
    rig (no ``simulator``) is warned of too: the rig's runout and lags would correct the simulated
    blocks. The one check of every --sim entry point."""
    record = rig.record
    if record is None or (not record.simulator and record.step is RecordStep.INITIAL):
        return None
    if not record.simulator:
        return (
            f"the calibration record {_where(rig)} was measured on the real rig, this run runs the simulator "
            f"scenario {scenario}: its runout, lags and gains are the rig's and correct the simulated blocks "
            f"wrongly (`orbitrig calibrate ... --sim --sim-config {scenario}` measures this one's)"
        )
    ours = digest(text)
    if record.simulator_sha256 == ours or (not record.simulator_sha256 and _same_file(record.simulator, scenario)):
        return None
    measured, runs = record.simulator, scenario
    if record.simulator_sha256:  # name the contents: the same file may have been edited since
        measured += f" (SHA-256 {record.simulator_sha256[:12]})"
        runs += f" (SHA-256 {ours[:12]}{': edited since' if _same_file(record.simulator, scenario) else ''})"
    return (
        f"the calibration record {_where(rig)} was measured on the simulator scenario {measured}, this "
        f"run runs {runs}: its runout, lags and gains are the other scenario's and correct this one's "
        f"blocks wrongly (`orbitrig calibrate ... --sim --sim-config {scenario}` measures this one's)"
    )


def _where(rig: RigConfig) -> str:
    """The active record's file, or for a run's stored copy (a resume) its name and where it is stored."""
    if Path(rig.file).is_file():
        return str(_record_file(rig))
    return f"{rig.calibration_record} (the copy stored in {rig.file.rsplit(':', 1)[0]})"


def _same_file(a: str, b: str) -> bool:
    """Whether the scenario files named `a` and `b` are one file (the same name, or resolving to it)."""
    return a == b or Path(a).resolve() == Path(b).resolve()


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
