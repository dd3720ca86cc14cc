"""Read a run directory (docs/storage.md) into plain data, without the rig.

`read_run(DIR)` reads the run's durable pieces (any run `--resume` can read, also one
cut short by a kill) or, in a directory holding only a consolidated ``run.h5``, that
file; both have the same groups (orbitrig.store.pieces). It returns a :class:`Run`: the
run's status and configuration, and one :class:`Point` per operating point with
its settings, its orbit table per load measuring system (as
:class:`reduction.table.OrbitTable`), the identifications the sweep stored, the
simulator's truth (``--sim`` runs), per-frequency coherence and the two-LMS
comparison. Everything is copied into memory, so the file is closed on return.

Units are SI as stored (rad/s, Pa, m, N); conversion to rpm, MPa, degrees is
left to the report.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from orbitrig.errors import ConfigError
from orbitrig.load_systems import LMS, LoadSystem
from orbitrig.store.errors import RunDirError as RunDirError  # its readers' error, imported from here too
from orbitrig.store.h5_values import json_attr, naming, open_h5, stored_values, text
from orbitrig.store.identity import header_software
from orbitrig.store.layout import READABLE_FORMATS, RUN_FILE, RunLayout, point_name
from orbitrig.store.layout import freq_dep_from_key, freq_dep_key as freq_dep_key  # storage's key form, read here
from orbitrig.store.index import NEVER_COMPLETED
from orbitrig.store.run_file_beside import journal_cut_short, whole_file_beside
from orbitrig.store.status import RunStatus
from orbitrig.store.stored_run import PROVENANCE_KEYS, Frequency, Settings, StoredIdentification
from orbitrig.store.stored_run import Point
from orbitrig.store.stored_run import Run as Run  # docs/api.md: orbitrig.store.reader.Run
from reduction.methods import Method
from rigunits import RPM

if TYPE_CHECKING:
    import h5py

    from reduction.table import OrbitTable


def _provenance_text(value: Any) -> str:
    """A provenance value of run.json as run.h5 stores it: text, a mapping as JSON."""
    return json.dumps(value) if isinstance(value, dict) else str(value)


def read_run(directory: str | Path, *, blocks: bool = True) -> Run:
    """Read the run in ``directory`` (docs/storage.md); ``blocks=False`` leaves out every
    point's averaged blocks (the results only: bounded memory for a summary).
    Raises :class:`RunDirError`."""
    directory = Path(directory)
    if not directory.exists():
        raise RunDirError(directory, "no such directory")
    if not directory.is_dir():
        raise RunDirError(directory, "not a directory (expected a run directory written by `orbitrig sweep --out DIR`)")
    layout = RunLayout(directory)
    if layout.has_pieces():
        return _read_pieces(layout, blocks)
    path = layout.run_file
    if not path.is_file():
        why = f"not an orbitrig run directory: no {RUN_FILE} (nor {layout.header.name}) in it"
        raise RunDirError(directory, why + _runs_inside(directory))
    return read_run_file(path, blocks=blocks, directory=directory)


def _runs_inside(directory: Path) -> str:
    """'; it holds runs in its folders (...): give those' when folders of ``directory`` are runs (the
    runs folder of `orbitrig serve --out`, a campaign's folder), else ""."""
    try:
        runs = sorted(
            d.name
            for d in directory.iterdir()
            if d.is_dir() and (RunLayout(d).has_pieces() or RunLayout(d).run_file.is_file())
        )
    except OSError:
        return ""
    if not runs:
        return ""
    shown = ", ".join(runs[:3]) + (f" and {len(runs) - 3} more" if len(runs) > 3 else "")
    return f"; it holds runs in its folders ({shown}): give those, e.g. {directory / runs[0]} or {directory}/*/"


def read_run_file(path: str | Path, *, blocks: bool = True, directory: Path | None = None) -> Run:
    """Read a consolidated run file (run.h5 or the h5 export, under any name: a copy sent to a
    colleague); the run's ``directory`` is the file itself unless given. Raises :class:`RunDirError`."""
    path = Path(path)
    directory = path if directory is None else directory
    with open_h5(path) as h5:
        fmt = text(h5.attrs.get("format"))
        if fmt not in READABLE_FORMATS:
            raise RunDirError(path, f"format attribute is {fmt or 'missing'!r}, expected {READABLE_FORMATS[-1]!r}")
        try:
            channels, units = _file_channels(h5)
            points = []
            for _, g in sorted(h5.get("points", {}).items()):
                with naming(g):
                    point = _new_point(g.attrs, g.name.rsplit("/", 1)[-1])
                for fname, fg in sorted(g.get("frequencies", {}).items()) if blocks else ():
                    with naming(fg):
                        point.frequencies.append(_frequency(fname, fg))
                _read_results(g, point)
                points.append(point)
            a = h5.attrs
            return Run(
                directory=directory,
                status=RunStatus.read(text(a.get("status"))),
                status_message=text(a.get("status_message")),
                sim=bool(a.get("sim", False)),
                software_version=text(a.get("software_version")),
                created=text(a.get("created")),
                matrix_name=text(a.get("matrix_name")),
                rig_config=text(a.get("rig_config")),
                matrix_config=text(a.get("matrix_config")),
                points=points,
                channels=channels,
                channel_units=units,
                sim_scenario_name=text(a.get("sim_scenario_name")),
                sim_scenario_config=text(a.get("sim_scenario_config")),
                provenance={k: text(a.get(k)) for k in PROVENANCE_KEYS},
                calibration_record_text=text(a.get("calibration_record_text")),
            )
        except (KeyError, ValueError, TypeError) as err:
            raise RunDirError(path, f"malformed run file: {err}") from err
        except OSError as err:
            raise RunDirError(path, f"cannot read ({err})") from err


def _file_channels(h5: h5py.File) -> tuple[list[str], list[str]]:
    """(names, units) of a run file's A/D channels in board order: its /channels and
    /channel_units, else (format orbitrig-run/1 stored none) as the rig configuration stored in
    it names them; ([], []) when that configuration cannot be read by this version."""
    if "channels" in h5:
        units = [text(c) for c in h5["channel_units"][()]] if "channel_units" in h5 else []
        return [text(c) for c in h5["channels"][()]], units
    try:
        return config_channels(text(h5.attrs.get("rig_config")), text(h5.attrs.get("calibration_record_text")))
    except ConfigError:
        return [], []


def config_channels(rig_config: str, record_text: str = "") -> tuple[list[str], list[str]]:
    """(names, units: N or m) of the A/D channels in board order as the rig configuration text
    `rig_config` stored in a run names them (`record_text`: the calibration record stored beside
    it). Raises ConfigError for a configuration this version cannot read."""
    from orbitrig.config import rig_from_text

    rig = rig_from_text(rig_config, "rig configuration stored in the run", record_text or None)
    return [c.name for c in rig.ordered_channels], [str(c.unit) for c in rig.ordered_channels]


def stored_channels(run: Run) -> tuple[list[str], list[str]]:
    """(names, units) of the run's A/D channels in board order, the rows of its stored arrays: its
    channel list, else (format orbitrig-run/1 stored none) as the rig configuration stored in it
    names them. RunDirError naming the run when that configuration cannot be read."""
    if run.channels:
        return run.channels, run.channel_units
    try:
        return config_channels(run.rig_config, run.calibration_record_text)
    except ConfigError as err:
        raise RunDirError(run.directory, f"cannot name the stored channels: {err}") from err


def read_run_points(directory: str | Path, indexes: list[int], *, blocks: bool = True, verified: bool = False) -> Run:
    """The run in pieces in ``directory`` with only the points ``indexes`` (the others not read):
    what a sweep has stored so far of those points, while it goes on; ``verified``: the points are
    complete as the caller has just checked them against their commit records (the sweep's closing
    table: the check before run.h5), not read and hashed again. Raises RunDirError."""
    layout = RunLayout(Path(directory))
    if not layout.has_pieces():
        raise RunDirError(Path(directory), "no run in pieces (a run being written) in it")
    return _read_pieces(layout, blocks, indexes, verified)


def _read_pieces(
    layout: RunLayout, blocks: bool = True, indexes: list[int] | None = None, verified: bool = False
) -> Run:
    from orbitrig.store.consolidate import read_header
    from orbitrig.store.errors import StorageError
    from orbitrig.store.index import PointState, point_state
    from orbitrig.store.journal import missing, read_journal

    try:
        header = read_header(layout)
        journal = read_journal(layout.journal)
    except StorageError as err:
        raise RunDirError(err.path, err.reason + whole_file_beside(layout, err.path)) from err
    run = Run(
        directory=layout.dir,
        status=journal.status,
        status_message=journal.status_message,
        sim=bool(header.get("sim", False)),
        software_version=header_software(header),
        created=str(header.get("created", "")),
        matrix_name=str(header.get("matrix_name", "")),
        rig_config=str(header.get("rig_config", "")),
        matrix_config=str(header.get("matrix_config", "")),
        points=[],
        channels=list(header.get("channels", [])),
        channel_units=list(header.get("channel_units", [])),
        torn=journal.torn,
        calibration_record_text=str(header.get("calibration_record_text", "")),
        warnings=[f"warning: {m}" for m in [missing(layout.journal), *journal.continued] if m],
    )
    if cut := journal_cut_short(layout, journal):
        run.warnings.append(cut)
    scenario = header.get("sim_scenario")
    if isinstance(scenario, dict):
        run.sim_scenario_name, run.sim_scenario_config = str(scenario.get("name", "")), str(scenario.get("text", ""))
    stored = header.get("provenance")
    prov = stored if isinstance(stored, dict) else {}
    ended = journal.status_at if journal.status.final else ""
    run.provenance = {k: _provenance_text(prov.get(k, "")) for k in PROVENANCE_KEYS[:-1]} | {"ended": ended}
    for index in layout.point_indexes() if indexes is None else indexes:
        state = PointState(index, True) if verified else point_state(layout, index)
        if not state.complete and not layout.point_file(index).exists():
            run.unbegun.append(index)  # cut between creating the point's folder and storing its settings
            continue
        try:
            point = read_point(layout, index, complete=state.complete, skipped=run.unreadable, blocks=blocks)
            point.problem = state.problem
        except RunDirError as err:
            if err.file != str(layout.point_file(index)):
                raise
            run.unreadable.append(str(err))
            continue
        run.points.append(point)
    return run


def read_point(
    layout: RunLayout, index: int, *, complete: bool, skipped: list[str] | None = None, blocks: bool = True
) -> Point:
    """One point of a run in pieces: settings, its readable blocks (unless blocks=False;
    the unreadable ones are named in `skipped`) and, when `complete`, its results.
    Raises RunDirError."""
    path = layout.point_file(index)
    try:
        settings = json.loads(path.read_bytes())
        point = _new_point({**settings, "complete": complete}, point_name(index))
    except (OSError, ValueError, KeyError, TypeError, RecursionError) as err:
        raise RunDirError(path, f"unreadable point settings ({type(err).__name__}: {err})") from err
    for tag in layout.block_tags(index) if blocks else ():
        try:
            with open_h5(layout.block_file(index, tag)) as fg:
                point.frequencies.append(_frequency(tag, fg))
        except (RunDirError, OSError, KeyError, ValueError) as err:
            if skipped is not None:
                skipped.append(f"{layout.block_file(index, tag)}: {err}")
    if complete:
        try:
            with open_h5(layout.results_file(index)) as rg:
                _read_results(rg, point)
        except (RunDirError, OSError, KeyError, ValueError, TypeError) as err:
            raise RunDirError(layout.results_file(index), f"malformed results of a complete point: {err}") from err
    return point


def _setting(a: h5py.AttributeManager | dict[str, Any], key: str, default: float | None = np.nan) -> float:
    """Setting ``key`` of a point as a float (``default`` when absent; None: required);
    ValueError naming the key when it is not a number."""
    if key not in a and default is not None:
        return default
    if key not in a:
        raise ValueError(f"setting {key!r} missing")
    try:
        return float(a[key])
    except (TypeError, ValueError):
        raise ValueError(f"setting {key!r} is not a number: {a[key]!r}") from None


def _new_point(a: h5py.AttributeManager | dict[str, Any], name: str) -> Point:
    spin = _setting(a, "spin", None)
    settings = Settings(
        spin=spin,
        spin_rpm=_setting(a, "spin_rpm", spin / RPM),
        recess_pressure=_setting(a, "recess_pressure"),
        pressure_ratio=_setting(a, "pressure_ratio"),
        static_eccentricity=_setting(a, "static_eccentricity"),
        dynamic_eccentricity=_setting(a, "dynamic_eccentricity"),
        orbit_radius=_setting(a, "orbit_radius"),
        label=text(a.get("label"), name),
    )
    complete = bool(a.get("complete", False))
    return Point(
        index=int(a.get("index", int(name))),
        name=name,
        complete=complete,
        settings=settings,
        problem="" if complete else NEVER_COMPLETED,
        software=text(a.get("software")),
    )


def _frequency(name: str, fg: h5py.File | h5py.Group) -> Frequency:
    fa = fg.attrs
    coh = np.asarray(fg["coherence"][()], dtype=float) if "coherence" in fg else None
    waveform = {k: stored_values(fg[k]) for k in _WAVEFORM if k in fg}
    return Frequency(
        name=name,
        orbit=float(fa.get("orbit", np.nan)),
        orbit_hz=float(fa.get("orbit_hz", np.nan)),
        direction=int(fa.get("direction", 1)),
        complete=bool(fa.get("complete", False)),
        coherence=coh,
        n_records=int(fa.get("n_records", 0)),
        measured_orbit_speed=float(fa.get("measured_orbit_speed", np.nan)),
        written=(float(fa.get("spin_written", np.nan)), float(fa.get("orbit_written", np.nan))),
        waveform=waveform,
    )


_WAVEFORM = ("mean", "slots", "dc", "phasors", "uncertainty")


def _table(tg: h5py.Group, spin: float) -> OrbitTable:
    from reduction.table import OrbitTable

    extra = {}  # orbit-table v2 columns, stored when the sweep had them
    if "n_records" in tg:
        extra["n_records"] = np.asarray(tg["n_records"][()], dtype=float)
    if "u" in tg:
        extra["u"] = np.asarray(tg["u"][()], dtype=float)
    return OrbitTable(
        spin=float(tg.attrs.get("spin", spin)),
        orbit=np.asarray(tg["orbit"][()], dtype=float),
        x=stored_values(tg["x"]).astype(complex),
        y=stored_values(tg["y"]).astype(complex),
        fx=stored_values(tg["fx"]).astype(complex),
        fy=stored_values(tg["fy"]).astype(complex),
        gamma2=np.asarray(tg["gamma2"][()], dtype=float) if "gamma2" in tg else None,
        **extra,
    )


def _load_system(name: str, group: h5py.Group) -> LoadSystem:
    """The load measuring system a results group is named after (ValueError naming the group)."""
    try:
        return LoadSystem(name)
    except ValueError:
        raise ValueError(f"{group.name}: {name!r} is not a load measuring system ({', '.join(LMS)})") from None


def _read_results(g: h5py.File | h5py.Group, point: Point) -> None:
    """The results groups (table, identification, truth, lms_comparison, runout_turns) of `point`."""
    for name, tg in sorted(g.get("table", {}).items()):
        with naming(tg):
            point.tables[_load_system(name, tg)] = _table(tg, point.settings.spin)
    for key, ig in sorted(g.get("identification", {}).items()):
        lms, model, fd_key = key.split("__", 2)
        ia = ig.attrs
        with naming(ig):
            result = json_attr(ia, "json")
        point.identifications.append(
            StoredIdentification(
                lms=_load_system(lms, ig),
                model=text(ia.get("model"), model),
                freq_dep=text(ia.get("freq_dep")) or freq_dep_from_key(fd_key),
                result=result,
                error=text(ia.get("error")) or None,
                method=text(ia.get("method")) or str((result or {}).get("method", Method.OLS.value)),
            )
        )
    for name in ("truth", "lms_comparison", "runout_turns"):
        if name in g:
            with naming(g[name]):
                setattr(point, name, json_attr(g[name].attrs, "json"))
