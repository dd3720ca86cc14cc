"""The rig's active calibration record (rig.toml's ``calibration_record``): its folder and file, and
whether it belongs to this rig: refused when measured on another rig or channel setup, edited
since its step wrote it, or (before a run on the rig itself) measured on the simulator; warned of
when a --sim run runs another scenario than it was measured on."""

from __future__ import annotations

from pathlib import Path

from orbitrig.config.home import shipped_config
from orbitrig.config.messages import key_line
from orbitrig.config.record_files import folder_of, list_names, read_record
from orbitrig.config.record_seal import check_seal, digest
from orbitrig.config.record_setup import check_setup, made_elsewhere
from orbitrig.config.records import CalibrationRecord, RecordStep
from orbitrig.config.rig import RigConfig
from orbitrig.errors import ConfigError


def record_folder(file: str) -> Path:
    """The calibration records' folder of the rig configuration ``file``: calibration/ beside it,
    or the shipped defaults' when there is no such folder (a rig.toml copied elsewhere alone, or
    text that is not from a file)."""
    beside = folder_of(file) if Path(file).is_file() else None
    return beside if beside is not None and beside.is_dir() else shipped_config() / "calibration"


def _record_file(rig: RigConfig) -> Path:
    """The file of the rig configuration's active calibration record (record_folder's NAME.toml)."""
    return record_folder(rig.file) / f"{rig.calibration_record}.toml"


def read_active_record(file: str, text: str, name: str) -> tuple[CalibrationRecord, str]:
    """(record, its text) of the active record ``name``; a missing one is a ConfigError naming the
    rig configuration, the line of ``calibration_record`` and the records of the folder searched."""
    folder = record_folder(file)
    if not (folder / f"{name}.toml").is_file():
        at = key_line(text, ("calibration_record",))
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
    at, key_at = key_line(record_text, ("rig",)), key_line(rig.text, ("calibration_record",))
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
    at = key_line(rig.record_text, ("simulator",))
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
