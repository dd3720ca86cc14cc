"""run.h5: the whole run in one HDF5 file, consolidated from the durable pieces.

The file is streamed to ``run.h5.tmp`` (`durable.StreamedH5`) and renamed into place
after an fsync: a reader finds the previous run.h5 or the new one, never a torn file,
memory stays bounded whatever the size of the run, and a full disk is an ordinary
StorageFullError. Built at the end of a run (`RunStore.finalize`) and by
`orbitrig export --format h5`. During a run, `RunImage` copies each point into the
temporary file as soon as it is committed, so the end of the run only adds the status
and the logs.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import numpy.typing as npt

from orbitrig.store.durable import StreamedH5
from orbitrig.store.errors import WRITE_ERRORS, StorageError, UnusableRunDir
from orbitrig.store.identity import header_software
from orbitrig.store.stored_run import CONFIG_SHA256, SEAL, VALIDITY
from orbitrig.store.strict_json import once_each
from orbitrig.store.index import PointState, scan
from orbitrig.store.journal import CAN_DTYPE, CAN_UNITS, DRIVE_DTYPE, DRIVE_UNITS, FIELD_MEANING, Journal, read_journal
from orbitrig.store.layout import FORMAT, POINT_ATTR_UNITS, READABLE_FORMATS, RunLayout, point_name
from orbitrig.store.annotate import annotate, annotate_attributes, annotate_dataset
from orbitrig.store.pieces import STR, fixed_text, put, strings
from rigunits import TEXT

log = logging.getLogger(__name__)
# text fields fixed-length when stored
EVENT_DTYPE = np.dtype([("t", "f8"), ("state", STR), ("message", STR)])
COMMAND_DTYPE = np.dtype([("at", STR), ("command", STR), ("by", STR), ("detail", STR)])


#: the JSON name of a parsed value's type, for messages
_JSON_TYPES: dict[type, str] = {
    list: "array",
    str: "string",
    int: "number",
    float: "number",
    bool: "boolean",
    type(None): "null",
    dict: "object",
}


def read_header(layout: RunLayout) -> dict[str, Any]:
    """run.json as a dict; UnusableRunDir when it is missing or not a run's header (a key given
    twice, a format this version does not read), StorageError when it cannot be read (an I/O error)."""
    try:
        header = json.loads(layout.header.read_bytes(), object_pairs_hook=once_each)
        if not isinstance(header, dict):
            raise ValueError(f"a JSON {_JSON_TYPES.get(type(header), 'value')}, not an object")
        if "format" not in header:
            raise ValueError("no 'format' key")
        if not str(header["format"]).startswith("orbitrig-run/"):
            raise ValueError(f"format {header['format']!r}")
    except FileNotFoundError:
        raise UnusableRunDir(layout.header, "missing: not a run directory of this version") from None
    except (ValueError, RecursionError) as err:
        raise UnusableRunDir(layout.header, f"not a readable run header ({type(err).__name__}: {err})") from err
    except OSError as err:
        raise StorageError(layout.header, f"not a readable run header ({type(err).__name__}: {err})") from err
    if header["format"] not in READABLE_FORMATS:
        raise UnusableRunDir(
            layout.header,
            f"format {header['format']!r}: a run of another orbitrig version; this one reads "
            f"{', '.join(READABLE_FORMATS)}",
        )
    for key, value in header.items():
        if key in _FIELDS and not _FIELDS[key][0](value):
            raise UnusableRunDir(
                layout.header,
                f"not a readable run header (field {key!r}: {_FIELDS[key][1]} expected, found {_shown(value)})",
            )
    return header


def _texts(v: object) -> bool:
    return isinstance(v, list) and all(isinstance(x, str) for x in v)


#: the fields of run.json whose type a reader relies on (any may be absent in an older run):
#: key -> (check, what the check wants, in words)
_FIELDS: dict[str, tuple[Callable[[object], bool], str]] = {
    **{
        k: (lambda v: isinstance(v, str), "a string")
        for k in (
            "software_version",
            "created",
            "matrix_name",
            "rig_config",
            "matrix_config",
            "calibration_record_text",
        )
    },
    "sim": (lambda v: isinstance(v, bool), "true or false"),
    "channels": (_texts, "an array of strings"),
    "channel_units": (_texts, "an array of strings"),
    "point_order": (
        lambda v: isinstance(v, list) and all(isinstance(i, int) and not isinstance(i, bool) for i in v),
        "an array of integers",
    ),
    "sim_scenario": (
        lambda v: isinstance(v, dict) and all(isinstance(v.get(k, ""), str) for k in ("name", "text")),
        "an object of strings name and text",
    ),
    "provenance": (lambda v: isinstance(v, dict), "an object"),
}


def _shown(value: object) -> str:
    """A value found in run.json, for a message: its JSON type and at most 60 characters of it."""
    text = json.dumps(value)
    return f"a JSON {_JSON_TYPES.get(type(value), 'object')} {text[:60]}{'...' if len(text) > 60 else ''}"


#: told (points copied, points to copy) as a consolidation copies each point into run.h5
Copied = Callable[[int, int], None]


def write_run_file(
    layout: RunLayout, dest: Path | None = None, progress: Copied | None = None, states: list[PointState] | None = None
) -> Path:
    """Consolidate the run directory `layout` into `dest` (default: its run.h5); `states`: its
    points as just verified (None: verified here)."""
    out = StreamedH5(dest or layout.run_file)
    try:
        build_run_file(out.file, layout, progress, states)
    except Exception as err:
        raise out.failed(err) from err
    return out.commit()


def build_run_file(
    f: h5py.File, layout: RunLayout, progress: Copied | None = None, states: list[PointState] | None = None
) -> None:
    """Write the whole run (header, every point's pieces, logs) into the open file `f`;
    `progress` is told each point copied; `states`: the points as just verified (None: verified here)."""
    states = scan(layout) if states is None else states
    _build(f, layout, read_header(layout), read_journal(layout.journal), states, set(), progress)


class RunImage:
    """run.h5 under construction in run.h5.tmp; `add_point` copies a committed point in."""

    def __init__(self, layout: RunLayout):
        self.layout = layout
        self._out: StreamedH5 | None = None
        self._done: set[int] = set()

    def add_point(self, index: int) -> None:
        """Copy committed point `index`; on any failure the file is dropped (`write` then
        consolidates from the pieces), because the point itself is safe in its pieces."""
        try:
            if self._out is None:
                self._out = StreamedH5(self.layout.run_file)
                self._out.file.create_group("points")
            if _add_point(self._out.file["points"], self.layout, index, True):
                self._done.add(index)
            self._out.file.flush()
        except Exception as err:  # noqa: BLE001 - h5py reports a failed write in several types
            log.warning("run.h5 will be consolidated at the end (cannot copy point %s now: %s)", point_name(index), err)
            self.close()

    def write(self, states: list[PointState], progress: Copied | None = None) -> Path:
        """Finish run.h5 (the points not copied yet are copied now, `progress` told each) and
        rename it into place; `states`: every point as just verified against its commit record."""
        out, done = self._out, self._done
        self._out, self._done = None, set()
        if out is None:
            return write_run_file(self.layout, progress=progress, states=states)
        try:
            header, journal = read_header(self.layout), read_journal(self.layout.journal)
            if any(i not in {st.index for st in states if st.complete} for i in done):
                out.discard()  # a copied point is no longer complete
                return write_run_file(self.layout, progress=progress, states=states)
            _build(out.file, self.layout, header, journal, states, done, progress)
        except Exception as err:
            raise out.failed(err) from err
        return out.commit()

    def copied(self) -> frozenset[int]:
        """The points copied into run.h5.tmp so far."""
        return frozenset(self._done)

    def close(self) -> None:
        if self._out is not None:
            self._out.discard()
        self._out, self._done = None, set()


def _build(
    f: h5py.File,
    layout: RunLayout,
    header: dict[str, Any],
    journal: Journal,
    states: list[PointState],
    done: set[int],
    progress: Copied | None = None,
) -> None:
    a = f.attrs
    a["format"] = FORMAT
    a["software_version"] = header_software(header)  # orbitrig's entry naming the code (provenance)
    for k in ("created", "rig_config", "matrix_config", "matrix_name"):
        a[k] = str(header.get(k, ""))
    a["sim"] = bool(header.get("sim", False))
    scenario = header.get("sim_scenario")
    if isinstance(scenario, dict):  # the simulator scenario of a --sim run: name and TOML text
        a["sim_scenario_name"], a["sim_scenario_config"] = str(scenario.get("name", "")), str(scenario.get("text", ""))
    a["status"], a["status_message"] = str(journal.status), journal.status_message
    _provenance(a, header, journal)
    a["software_versions"] = json.dumps(_point_software(layout, states))  # two or more: say so
    f.create_dataset("channels", data=fixed_text(header.get("channels", [])))
    f.create_dataset("channel_units", data=fixed_text(header.get("channel_units", [])))
    pts = f.require_group("points")
    left = [st for st in states if st.index not in done]
    for n, st in enumerate(left, 1):
        _add_point(pts, layout, st.index, st.complete)
        if progress is not None:
            progress(n, len(left))
    _write_logs(f.create_group("logs"), journal)
    annotate_attributes(f)
    for name in ("channels", "channel_units"):
        annotate_dataset(f[name])
    annotate(f["logs"])


def _provenance(a: h5py.AttributeManager, header: dict[str, Any], journal: Journal) -> None:
    """Who made the run, with what, where, when (orbitrig.run.provenance), as root attributes."""
    prov = header.get("provenance")
    if not isinstance(prov, dict):
        return  # a run written before provenance was recorded
    for k in (
        "operator",
        "rig_id",
        "host",
        "calibration_record",
        "calibration_record_sha256",
        "started",
        SEAL,
        VALIDITY,
        *CONFIG_SHA256,
    ):
        a[k] = str(prov.get(k, ""))
    a["sensor_serials"] = json.dumps(prov.get("sensor_serials", {}))
    a["calibration_record_text"] = str(header.get("calibration_record_text", ""))
    a["ended"] = journal.status_at if journal.status.final else ""


def _add_point(pts: h5py.Group, layout: RunLayout, index: int, complete: bool) -> bool:
    """Copy one point's pieces into /points/PPPP; False when its settings are unreadable."""
    settings = _settings(layout, index)
    if settings is None:
        return False  # a point directory without readable settings: nothing to show
    g = pts.create_group(point_name(index))
    g.attrs.update(settings)
    g.attrs["complete"] = complete
    g.attrs["units_of_attributes"] = POINT_ATTR_UNITS
    annotate_attributes(g)
    freqs = g.create_group("frequencies")
    for tag in layout.block_tags(index):
        _copy_root(layout.block_file(index, tag), freqs, tag)
    if complete:
        _copy_root(layout.results_file(index), g, None)
    return True


def _point_software(layout: RunLayout, states: list[PointState]) -> list[str]:
    """The software that measured the points (each point.json's ``software``), each once, in point order."""
    seen: dict[str, None] = {}
    for st in states:
        s = _settings(layout, st.index) or {}
        if s.get("software"):
            seen.setdefault(str(s["software"]), None)
    return list(seen)


def _settings(layout: RunLayout, index: int) -> dict[str, Any] | None:
    try:
        s = json.loads(layout.point_file(index).read_bytes())
    except (OSError, ValueError, RecursionError):
        return None
    return s if isinstance(s, dict) else None


def _copy_root(path: Path, dest: h5py.Group, name: str | None) -> None:
    """Copy a piece's root into `dest` (as group `name`, or its members when None). A piece
    that cannot be read is a StorageError naming it; a failed write of `dest`'s file (full
    disk: an errno of WRITE_ERRORS) raises its OSError for the caller, which names that file."""
    try:
        with h5py.File(path, "r") as src:
            if name is None:
                for k in src:
                    src.copy(src[k], dest, name=k)
            else:
                src.copy(src["/"], dest, name=name)
    except OSError as err:
        if err.errno in WRITE_ERRORS:
            raise
        raise StorageError(path, f"cannot read this piece of the run: {err}") from err


def _fields(dtype: np.dtype[np.void]) -> tuple[str, ...]:
    """The field names of a compound dtype (numpy's stubs: None for a plain one)."""
    if dtype.names is None:
        raise ValueError(f"{dtype} is not a compound dtype")
    return dtype.names


def _fixed_rows(rows: Sequence[tuple[object, ...]], dtype: np.dtype[np.void]) -> npt.NDArray[np.void]:
    """Log rows as a compound array whose text fields are fixed-length (``fixed_text``)."""
    data = np.array(rows, dtype=dtype) if rows else np.zeros(0, dtype)
    cols = {k: fixed_text(data[k]) if dtype[k] == STR else data[k] for k in _fields(dtype)}
    out = np.zeros(len(data), [(k, v.dtype) for k, v in cols.items()])
    for k, v in cols.items():
        out[k] = v
    return out


def _write_logs(lg: h5py.Group, journal: Journal) -> None:
    put(
        lg,
        "events",
        _fixed_rows(journal.events, EVENT_DTYPE),
        "t: s since the run started",
        fields=strings(_fields(EVENT_DTYPE)),
        field_units=strings(("s", TEXT, TEXT)),
    )
    put(
        lg,
        "commands",
        _fixed_rows(journal.commands, COMMAND_DTYPE),
        "at: ISO 8601 UTC; by: who sent the command",
        fields=strings(_fields(COMMAND_DTYPE)),
        field_units=strings([TEXT] * len(_fields(COMMAND_DTYPE))),
    )
    for name, rows, dt, units in (
        ("can", journal.can, CAN_DTYPE, CAN_UNITS),
        ("drives", journal.drives, DRIVE_DTYPE, DRIVE_UNITS),
    ):
        data = np.array(rows, dtype=dt) if rows else np.zeros(0, dt)
        put(
            lg,
            name,
            data,
            TEXT,  # one unit per field (field_units; units_<field> once annotated)
            fields=strings(_fields(dt)),
            meaning="; ".join(
                f"{n}: {u}" + (f" ({FIELD_MEANING[n]})" if n in FIELD_MEANING else "")
                for n, u in zip(_fields(dt), units)
            ),
            field_units=strings(units),
        )
