"""The calibration records' folder beside the rig configuration (docs/calibration.md): dated
record names (``2026-11-26T214458Z-loads``, UTC), reading, writing (never over an existing
record, not even one another process writes at that instant; a record dated as it is written,
`write_dated`, takes the next free second; each holds the SHA-256 of its own text, record_seal,
which also owns `digest`, the SHA-256 a run records), and making a record active: the rig file's ``calibration_record`` line set or
added, the file replaced as one durable step.
"""

from __future__ import annotations

import datetime as _dt
import os
import re
import stat
import time
import tomllib
from collections.abc import Callable
from pathlib import Path

from orbitrig.config.record_seal import NOTE, PLACEHOLDER, seal, without_seal
from orbitrig.config.records import CalibrationRecord
from orbitrig.config.toml_out import render
from orbitrig.errors import ConfigError
from rigunits import now_iso, record_stamp, record_stamp_date

FOLDER = "calibration"
#: a record's name: its record_stamp (rigunits), a dash, its step (the rig.toml's calibration_record too)
NAME_PATTERN = r"^\d{4}-\d\d-\d\dT\d{6}Z-[a-z]+$"
NAME = re.compile(NAME_PATTERN)
NAME_RULE = "a record name is <date>T<hhmmss>Z-<step> (e.g. 2026-11-26T214904Z-loads): no folder, no suffix"
RECORD_KEY = re.compile(r"""^([ \t]*calibration_record[ \t]*=[ \t]*)("[^"\n]*"|'[^'\n]*')""", re.MULTILINE)
TABLE_HEADER = re.compile(r"^[ \t]*\[")
TOP_KEY = re.compile(r"^[ \t]*([A-Za-z0-9_-]+)[ \t]*=")
#: s between looks for a free second when a record of the same step is named by this one already
FREE_SECOND_POLL_S = 0.05


def folder_of(rig_file: str | Path) -> Path:
    """The calibration records' folder of the rig configuration ``rig_file``."""
    return Path(rig_file).resolve().parent / FOLDER


def record_name(date: str, step: str) -> str:
    """The file stem of a record made at ``date`` (ISO 8601 UTC) by ``step``."""
    return f"{record_stamp(_dt.datetime.fromisoformat(date))}-{step}"


def record_from_text(text: str, file: str) -> CalibrationRecord:
    """The record of ``text``; its digest's line (record_seal) is the file's, not the record's."""
    from orbitrig.config.reading import build_model, parse_toml

    return build_model(CalibrationRecord, parse_toml(without_seal(text), file), file, text)


def name_problem(name: str) -> str | None:
    """What is wrong with ``name`` as a calibration record's (NAME, NAME_RULE); None: a plain record name."""
    return None if NAME.fullmatch(name) else f"{name!r} is not a calibration record name: {NAME_RULE}"


def read_record(folder: Path, name: str) -> tuple[CalibrationRecord, str]:
    """(record, its text) of record ``name`` in ``folder``; ConfigError naming the file, or the
    folder and NAME_RULE for a ``name`` that is not a plain record name (``../rig``: no file
    outside ``folder`` is read)."""
    from orbitrig.config.reading import read_text

    problem = name_problem(name)
    if problem is not None:
        raise ConfigError(str(folder), [problem])
    path = Path(folder) / f"{name}.toml"
    if not path.is_file():
        known = ", ".join(list_names(folder)) or "none"
        raise ConfigError(str(path), [f"no calibration record {name!r} (records in {folder}: {known})"])
    text, file = read_text(path)
    return record_from_text(text, file), text


def list_names(folder: Path) -> list[str]:
    """The record names in ``folder``, oldest first to the second (by name; `read_all`: to the ms)."""
    return sorted(p.stem for p in Path(folder).glob("*.toml")) if Path(folder).is_dir() else []


def read_all(folder: Path) -> list[tuple[str, CalibrationRecord | ConfigError, str]]:
    """Every record of ``folder`` as (name, record or the ConfigError of one that cannot be read,
    its text), in the order they were taken: by their ``date`` (written as each record is, to the
    millisecond: two steps of one second in the order they ran), then by name (the same
    millisecond; files carry no sequence and Linux keeps no creation time a file system gives
    every program); one that cannot be read by its name's date, to the second."""
    found: list[tuple[_dt.datetime, str, CalibrationRecord | ConfigError, str]] = []
    for name in list_names(folder):
        try:
            record, text = read_record(folder, name)
            found.append((_dt.datetime.fromisoformat(record.date), name, record, text))
        except ConfigError as err:
            found.append((_name_date(name), name, err, ""))
    return [(name, record, text) for _, name, record, text in sorted(found, key=lambda f: (f[0], f[1]))]


def _name_date(name: str) -> _dt.datetime:
    """The UTC date a record's name starts with (to the second); the latest date for another name."""
    return record_stamp_date(name) or _dt.datetime.max.replace(tzinfo=_dt.timezone.utc)


def write_record(folder: Path, record: CalibrationRecord, header: str = "") -> tuple[str, str]:
    """Write ``record`` under its dated name (never over an existing one), holding the SHA-256 of
    its own text (record_seal: its ``sha256`` line, which the digest leaves out); (name, text).
    A record of that name there already (also one written at that instant by another process)
    raises ConfigError naming it."""
    name, text = _sealed(folder, record, header)
    path = Path(folder) / f"{name}.toml"
    if not _create(path, text):
        raise ConfigError(str(path), ["a record of that name exists already (one step per second)"])
    return name, text


def write_dated(
    folder: Path, record: CalibrationRecord, header: Callable[[CalibrationRecord], str] = lambda _: ""
) -> tuple[CalibrationRecord, str, str]:
    """Write ``record`` dated now, ``header(dated record)`` on top, as write_record; when its
    step's record of this second is there already (a step or init run twice within one second,
    another process's), dated at the next free second: no step's record is lost for its name, none
    written over. (The record as dated, its name, its text)."""
    while True:
        dated = record.model_copy(update={"date": now_iso()})
        name, text = _sealed(folder, dated, header(dated))
        if _create(Path(folder) / f"{name}.toml", text):
            return dated, name, text
        time.sleep(FREE_SECOND_POLL_S)


def _sealed(folder: Path, record: CalibrationRecord, header: str) -> tuple[str, str]:
    """(name, sealed text) of ``record``, the text checked to read back as it."""
    name = record_name(record.date, record.step)
    data = record.model_dump(mode="json", exclude_none=True) | {"sha256": PLACEHOLDER}
    text = seal(render(data, header, {"sha256": NOTE}))
    record_from_text(text, str(Path(folder) / f"{name}.toml"))  # what is written reads back
    return name, text


def _create(path: Path, text: str) -> bool:
    """Write ``text`` into ``path`` made new (O_EXCL: never over a file there, whoever made it);
    False when a file of that name is there. ConfigError naming it when it cannot be written (a
    file begun is removed)."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC, 0o644)
    except FileExistsError:
        return False
    except OSError as err:
        raise ConfigError(str(path), [f"cannot write the record: {err.strerror or err}"]) from err
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
    except OSError as err:
        path.unlink(missing_ok=True)
        raise ConfigError(str(path), [f"cannot write the record: {err.strerror or err}"]) from err
    return True


def activate(rig_file: str | Path, name: str) -> None:
    """Make ``name`` the active record of the rig configuration ``rig_file`` (its
    ``calibration_record`` line; added among the top-level keys when missing). Nothing else changes:
    the file is replaced as one durable step (orbitrig.store.durable, its mode kept; a symbolic link
    followed), so a full disk or a kill leaves it as it was. A file that cannot be written (no write
    permission bit, immutable, a full disk) raises ConfigError naming it, the file unchanged."""
    path = Path(rig_file).resolve()
    try:
        text = path.read_bytes().decode("utf-8")
    except OSError as err:
        raise ConfigError(str(rig_file), [f"cannot read it: {err.strerror or err}"]) from err
    if RECORD_KEY.search(text):
        text = RECORD_KEY.sub(lambda m: f'{m.group(1)}"{name}"', text, count=1)
    else:
        placed = _with_record_key(text, name)
        if placed is None:
            raise ConfigError(str(path), [f'cannot add calibration_record = "{name}": add it among the top-level keys'])
        text = placed
    _replace(path, text.encode("utf-8"), str(rig_file))


def _replace(path: Path, data: bytes, shown: str) -> None:
    """``data`` as the new content of the existing file ``path`` (temp name, fsync, rename), its
    permission bits kept; refused (ConfigError naming ``shown``) when it has no write bit or the
    write fails, the file unchanged."""
    from orbitrig.store.durable import atomic_file
    from orbitrig.store.errors import StorageError, StorageFullError

    mode = stat.S_IMODE(path.stat().st_mode)
    if not mode & 0o222 or not os.access(path, os.W_OK):
        why = f"it is read-only (mode {mode:o})" if not mode & 0o222 else "write access refused (immutable?)"
        raise ConfigError(shown, [f"cannot write it: {why}; left unchanged"])
    try:
        with atomic_file(path) as f:
            os.fchmod(f.fileno(), mode)
            f.write(data)
    except StorageError as err:
        why = err.problem if isinstance(err, StorageFullError) else err.reason
        raise ConfigError(shown, [f"{why}; left unchanged"]) from None


def _with_record_key(text: str, name: str) -> str | None:
    """``text`` with ``calibration_record = "name"`` among its top-level keys: after ``name = ...``,
    else after the last top-level key, else above the first table (and its comments), else on
    top; the first place where the text reads back as before plus that key (None: no such place)."""
    lines = text.splitlines(keepends=True)
    nl = "\r\n" if "\r\n" in text else "\n"
    first = next((i for i, ln in enumerate(lines) if TABLE_HEADER.match(ln)), len(lines))
    keys = [i for i in range(first) if TOP_KEY.match(lines[i])]
    named = [i for i in keys if lines[i].split("=")[0].strip() == "name"]
    above = first
    while above > 0 and lines[above - 1].lstrip().startswith("#"):
        above -= 1
    want = _toml(text)
    if want is not None:
        want["calibration_record"] = name
    for at, gap in [(i + 1, "") for i in named[:1] + keys[-1:]] + [(above, nl), (0, "")]:
        head = "".join(lines[:at])
        head += nl if head and not head.endswith("\n") else ""
        out = f'{head}calibration_record = "{name}"{nl}{gap if at < len(lines) else ""}' + "".join(lines[at:])
        if want is None or _toml(out) == want:
            return out
    return None


def _toml(text: str) -> dict | None:
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError:
        return None
