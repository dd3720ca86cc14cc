"""Units and descriptions on every dataset and attribute of an orbitrig HDF5 file.

Applied to each HDF5 image before it is written (the pieces and run.h5), so the files describe themselves to any reader:

- every numeric dataset has ``units`` (a unit string pint parses; "1" dimensionless,
  "count", "degree", "N s/m (rad/s)^-1") or, when its entries differ, one attribute per
  entry: ``units_<channel>`` (per A/D channel), ``units_<coefficient>`` (per coefficient
  key), ``units_<column>`` / ``units_<field>`` (per column of a table or log);
- every dataset has ``description``;
- every attribute A of a group or dataset has ``A__description``, and a numeric one
  ``A__units`` (HDF5 attributes cannot carry attributes).

Text datasets and attributes have no unit. orbitrig.store.descriptions is the one list of what
each name means; a name missing from it is described as UNDOCUMENTED, which the tests refuse.
"""

from __future__ import annotations

import h5py
import numpy as np
from h5py import h5a, h5s, h5t

from orbitrig.store.descriptions import ATTRIBUTES, DATASETS, PER_CHANNEL, PER_COEFFICIENT, PER_SOURCE, UNDOCUMENTED
from orbitrig.store.layout import U_COLUMNS, U_UNITS
from rigunits import ONE, TEXT, coefficient_unit

#: attributes that annotate (they describe others; no description of their own)
_ANNOTATIONS = {
    "units",
    "description",
    "convention",
    "dimensions",
    "columns",
    "rows",
    "fields",
    "field_units",
    "names",
    "meaning",
}


#: a scalar UTF-8 text attribute, as h5py writes a Python str (variable length)
_TEXT = h5py.string_dtype("utf-8")
_TEXT_FILE_TYPE = h5t.py_create(_TEXT, logical=True)
_TEXT_MEMORY_TYPE = h5t.py_create(_TEXT)
_SCALAR = h5s.create_simple(())


def _put_text(obj: h5py.HLObject, name: str, text: str) -> None:
    """``obj.attrs[name] = text`` in the file format h5py gives it, through HDF5's own calls:
    a third of h5py's time per attribute, and a piece carries hundreds of these."""
    oid, key = obj.id, name.encode("utf-8")
    if h5a.exists(oid, key):
        h5a.delete(oid, key)
    attr = h5a.create(oid, key, _TEXT_FILE_TYPE, _SCALAR)
    try:
        attr.write(np.asarray(text, dtype=_TEXT), mtype=_TEXT_MEMORY_TYPE)
    finally:
        attr.close()


def _is_text(obj: h5py.HLObject, name: str) -> bool:
    """Whether attribute `name` of `obj` holds text (read from its type, not its value)."""
    return h5a.open(obj.id, name.encode("utf-8")).dtype.kind in "OSU"


def _per_entry_rule(ds: h5py.Dataset, rule: str, names_at: dict[str, np.ndarray]) -> dict[str, str]:
    """units_<entry> attributes of a dataset whose entries have different units (`names_at`: the
    coefficient names read so far, by group)."""
    g = ds.parent
    if rule.startswith(PER_CHANNEL):
        host = g if "channels" in g.attrs else g.file
        names = host.attrs["channels"] if "channels" in g.attrs else host["channels"][()]
        units = g.attrs["channel_units"] if "channels" in g.attrs else host["channel_units"][()]
        suffix = rule[len(PER_CHANNEL) :]
        return {_s(n): _s(u) + suffix for n, u in zip(names, units)}
    if rule == PER_COEFFICIENT:
        names = ds.attrs["names"] if "names" in ds.attrs else _names_near(g, names_at)
        return {_s(n): coefficient_unit(_s(n)) for n in names}
    if rule == PER_SOURCE:
        return {_s(n): _source_unit(_s(n)) for n in g["sources"][()]}
    if rule == "<column>":
        return dict(zip(U_COLUMNS, U_UNITS))
    fields = list(ds.dtype.names or ())
    units = [_s(u) for u in ds.attrs.get("field_units", ["s"] + [TEXT] * (len(fields) - 1))]
    return {f: u if ds.dtype[f].kind in "fiub" else TEXT for f, u in zip(fields, units)}


def _names_near(g: h5py.Group, names_at: dict[str, np.ndarray]) -> np.ndarray:
    """The coefficient names of a fit's group (or of its parent), read once per group."""
    if g.name not in names_at:
        names_at[g.name] = g["names"][()] if "names" in g else g.parent["names"][()]
    return names_at[g.name]


def _source_unit(name: str) -> str:
    kind = name.rsplit(".", 1)[-1]
    return {"phase": "rad", "delay": "s"}.get(kind, "1")


def _s(v: object) -> str:
    return v.decode("utf-8") if isinstance(v, bytes) else str(v)


def annotate(f: h5py.Group) -> None:
    """Units and descriptions on every dataset and attribute under ``f`` (see the module docstring)."""
    names_at: dict[str, np.ndarray] = {}
    annotate_attributes(f)
    f.visititems(
        lambda _, obj: annotate_dataset(obj, names_at) if isinstance(obj, h5py.Dataset) else annotate_attributes(obj)
    )


def annotate_dataset(ds: h5py.Dataset, names_at: dict[str, np.ndarray] | None = None) -> None:
    """``description`` and units (``units`` or ``units_<entry>``) of one dataset, and its attributes'
    (`names_at`: coefficient names already read, by group, shared over one file's datasets)."""
    name = ds.name.rsplit("/", 1)[-1]
    units, description = DATASETS.get(name, (ONE if ds.dtype.kind in "biufc" else "", UNDOCUMENTED))
    annotate_attributes(ds)
    _put_text(ds, "description", description)
    if units.startswith("<"):  # entries with different units: one attribute per entry
        if "units" in ds.attrs:
            del ds.attrs["units"]
        per_entry = _per_entry_rule(ds, units, {} if names_at is None else names_at)
        for entry, unit in per_entry.items():  # "" for a text field of a log
            _put_text(ds, f"units_{entry}", unit)
    elif ds.dtype.kind not in "OS":  # text has no unit
        _put_text(ds, "units", _with_exponents(ds, units) or "1")


def _with_exponents(ds: h5py.Dataset, units: str) -> str:
    """A power-fit term's unit with its exponent ({m}, {n}, {p}) from its group's ``exponents``."""
    if "{" not in units:
        return units
    exps = ds.parent.attrs.get("exponents", (1, 1, 1))
    return units.format(**dict(zip("mnp", (int(e) for e in exps))))


def annotate_attributes(obj: h5py.HLObject) -> None:
    """``A__description`` (and ``A__units`` when numeric) for every attribute A of ``obj``."""
    for name in list(obj.attrs):
        if name in _ANNOTATIONS or "__" in name or name.startswith("units_"):
            continue
        units, description = ATTRIBUTES.get(name, ("", UNDOCUMENTED))
        _put_text(obj, f"{name}__description", description)
        if not _is_text(obj, name):
            _put_text(obj, f"{name}__units", units or "1")
