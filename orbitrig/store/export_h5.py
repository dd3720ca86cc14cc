"""`orbitrig export RUN --format h5`: the whole run in one HDF5 file that GNU Octave's
``load`` reads completely, as h5py and MATLAB do.

run.h5 (docs/storage.md) is laid out for h5py: complex datasets are compounds with members
``r``, ``i`` (h5py reads them as complex), the logs are compound tables and the metadata are
attributes. GNU Octave's ``load`` maps only compounds with members ``real``, ``imag`` (others
it reads as zeros or skips), cannot read HDF5 booleans (enums) and ignores attributes. The
export is the same tree with

- every complex dataset a compound of float64 members ``real``, ``imag``;
- every log (``/logs/events`` ...) a group with one dataset per field (text fixed-length),
  each with a ``description`` and, when numeric, its ``units`` (the log's ``units_<field>``);
- every text dataset fixed-length, every boolean dataset uint8 (1 true, 0 false);
- every attribute also a dataset ``/attributes/<path of its object>/<name>`` (text
  fixed-length, booleans uint8); an attribute whose name is taken there by a member's
  group is written as ``<name>_attribute``.

The attributes themselves stay, so h5py and MATLAB users read the metadata where run.h5 has
it. Each identification group also gets the fit's single values that run.h5 keeps only in its
``json`` (export_content.FIT_QUALITY: ``interval``, ``confidence_level``, ``k`` of U,
``interval_95_basis``; dof,
chi2, p_value, aic, bic are there already), each with ``__description`` (and ``__units``), so
every export carries the same fit properties. Each point's ``runout_turns`` group (its ``json``
attribute as in run.h5) also gets one dataset per field of export_content.RUNOUT_TURNS (the
block's spin turns per board revolution: ``orbit_hz``, ``direction``, ``commanded``, ``fitted``,
``u``, ``resolved`` uint8, ``used``, ``unfitted`` text), each with ``description`` and ``units``.
orbitrig's readers (orbitrig.store.reader) read
both layouts.
"""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
from h5py import h5d, h5s, h5t

from orbitrig.store import export_content as content
from orbitrig.store.consolidate import build_run_file
from orbitrig.store.durable import StreamedH5
from orbitrig.store.errors import RunDirError, storage_error
from orbitrig.store.fit_record import fit_record
from orbitrig.store.h5_values import json_attr
from orbitrig.store.layout import RunLayout
from orbitrig.store.pieces import fixed_text
from orbitrig.store.h5_values import OCTAVE_COMPLEX, stored_values

ATTRIBUTES = "attributes"


def export_h5(layout: RunLayout, out: Path) -> Path:
    """Write OUT/run.h5 in the layout above, from the run's pieces or (a directory holding
    only run.h5) from its run.h5. Raises RunDirError when OUT/run.h5 is the run's own file."""
    path = out / layout.run_file.name
    if path.resolve() == layout.run_file.resolve():
        raise RunDirError(path, "the h5 export would replace the run's own run.h5: export it to another folder (--out)")
    dest = StreamedH5(path)
    try:
        if layout.has_pieces():
            build_run_file(dest.file, layout)
        else:
            _copy_run_file(layout.run_file, dest.file)
        fit_quality_attributes(dest.file)
        runout_turns_datasets(dest.file)
        octave_layout(dest.file)
    except Exception as err:
        raise dest.failed(err) from err
    return dest.commit()


def _copy_run_file(src_path: Path, f: h5py.File) -> None:
    try:
        src = h5py.File(src_path, "r")
    except OSError as err:
        raise storage_error(src_path, "read", err) from err
    with src:
        f.attrs.update(src.attrs)
        for name in src:
            src.copy(src[name], f, name=name)


def fit_quality_attributes(f: h5py.File) -> None:
    """Each identification group of the run file `f` with the FIT_QUALITY values of its fit
    (export_content.fit_quality of its ``json``) that it lacks as attributes."""
    for point in f.get("points", {}).values():
        for g in point.get("identification", {}).values():
            result = json_attr(g.attrs, "json")
            if not isinstance(result, dict):
                continue  # a refused model: no fit
            fit = fit_record(0, None, str(g.attrs.get("model", "")), "", "", result)
            for name, value in content.fit_quality(fit).items():
                if name in g.attrs:
                    continue
                unit, meaning = content.FIT_QUALITY[name]
                g.attrs[name], g.attrs[f"{name}__description"] = value, meaning
                if unit:
                    g.attrs[f"{name}__units"] = unit


def runout_turns_datasets(f: h5py.File) -> None:
    """Each point's ``runout_turns`` group of the run file `f` with what its ``json`` holds as one
    dataset per field (export_content.RUNOUT_TURNS, one value per block), each with a
    ``description`` and, when numeric, its ``units``; ``resolved`` uint8, ``unfitted`` text."""
    for point in f.get("points", {}).values():
        g = point.get("runout_turns")
        turns = json_attr(g.attrs, "json") if isinstance(g, h5py.Group) else None
        if not isinstance(turns, dict):
            continue
        for name, (values, unit) in content.runout_turns_columns(turns).items():
            if name in g:
                del g[name]  # a file exported before
            ds = g.create_dataset(name, data=fixed_text(values) if values.dtype.kind == "U" else values)
            ds.attrs["description"] = content.RUNOUT_TURNS[name][1]
            if unit:
                ds.attrs["units"] = unit


def octave_layout(f: h5py.File) -> None:
    """Rewrite the open run file `f` in place into the layout of the module docstring."""
    if ATTRIBUTES in f:  # a file exported before: mirrored again
        del f[ATTRIBUTES]
    tables: list[h5py.Dataset] = []
    f.visititems(lambda _, obj: tables.append(obj) if _is_table(obj) else None)
    for ds in tables:  # first: their columns' attributes are mirrored too
        _table_as_columns(ds)
    objects: list[h5py.Group | h5py.Dataset] = [f]
    f.visititems(lambda _, obj: objects.append(obj))
    mirror = f.create_group(ATTRIBUTES)
    with_attrs = [
        (o, mirror.require_group(o.name.lstrip("/")) if o.name != "/" else mirror) for o in objects if o.attrs
    ]
    taken = {o.name for o, _ in with_attrs}  # every destination group exists before any attribute is written
    for obj, dest in with_attrs:
        _mirror_attributes(obj, dest, taken)
    for ds in (o for o in objects if isinstance(o, h5py.Dataset)):
        if ds.dtype.kind in "cbO":  # complex (h5py's r, i), boolean, variable-length text
            _replace(ds, _octave_value(stored_values(ds)))


def _is_table(obj: h5py.HLObject) -> bool:
    """A compound table (a log), not a complex compound (``real``, ``imag``)."""
    names = obj.dtype.names if isinstance(obj, h5py.Dataset) else None
    return names is not None and set(names) != {"real", "imag"}


def _octave_value(data: np.ndarray) -> np.ndarray:
    """`data` as Octave reads it (unchanged when it reads it already)."""
    if data.dtype.kind == "c":
        out = np.empty(data.shape, OCTAVE_COMPLEX)
        out["real"], out["imag"] = data.real, data.imag
        return out
    if data.dtype.kind == "b":
        return data.astype(np.uint8)
    if data.dtype.kind in "OU":  # variable-length text (h5py reads a dataset's as bytes)
        text = [v.decode("utf-8") if isinstance(v, bytes) else v for v in data.ravel()]
        return fixed_text(text).reshape(data.shape)
    return data


def _replace(ds: h5py.Dataset, data: np.ndarray) -> None:
    parent, name, attrs = ds.parent, ds.name.rsplit("/", 1)[-1], dict(ds.attrs)
    del parent[name]
    new = parent.create_dataset(name, data=data)
    new.attrs.update(attrs)


def _table_as_columns(ds: h5py.Dataset) -> None:
    """A compound table (a log) -> a group of the same name with one dataset per field, each
    with a description and, when numeric, the field's unit (the table's ``units_<field>``)."""
    parent, name, attrs, data = ds.parent, ds.name.rsplit("/", 1)[-1], dict(ds.attrs), ds[()]
    del parent[name]
    g = parent.create_group(name)
    g.attrs.update(attrs)
    what = str(attrs.get("description", name))
    for field in data.dtype.names:
        column = g.create_dataset(field, data=_octave_value(np.asarray(data[field])))
        column.attrs["description"] = f"field {field} of {what} (one value per row of the log)"
        unit = attrs.get(f"units_{field}")
        if unit and column.dtype.kind in "biuf":  # text has no unit
            column.attrs["units"] = unit


def _mirror_attributes(obj: h5py.Group | h5py.Dataset, dest: h5py.Group, taken: set[str]) -> None:
    """Each attribute of `obj` as a dataset in `dest`; `taken`: the HDF5 names of the objects
    whose attributes have a group of that name in the mirror."""
    for key, value in obj.attrs.items():
        name = key.replace("/", "_")
        if f"{obj.name.rstrip('/')}/{name}" in taken:
            name += "_attribute"
        data = np.asarray(value.encode("utf-8") if isinstance(value, str) else value)
        _small_dataset(dest, name, _octave_value(data))


def _small_dataset(group: h5py.Group, name: str, data: np.ndarray) -> None:
    """A dataset through h5py's low-level API: several times faster than `create_dataset`
    for the thousands of small ones the attributes make."""
    space = h5s.create(h5s.SCALAR) if data.ndim == 0 else h5s.create_simple(data.shape)
    ds = h5d.create(group.id, name.encode("utf-8"), h5t.py_create(data.dtype), space)
    if data.size:
        ds.write(h5s.ALL, h5s.ALL, np.ascontiguousarray(data))
