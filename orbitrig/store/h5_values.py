"""Values as HDF5 keeps them, read back as plain Python and numpy: text attributes (str or
bytes), JSON attributes, complex datasets in either layout, and a file opened for reading."""

from __future__ import annotations

import json
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from orbitrig.store.errors import RunDirError

if TYPE_CHECKING:  # h5py is imported when a file is opened
    import h5py

#: a complex dataset in the h5 export's layout (orbitrig.store.export_h5), which GNU Octave reads
OCTAVE_COMPLEX = np.dtype([("real", "<f8"), ("imag", "<f8")])


def text(value: Any, default: str = "") -> str:
    """An attribute as text (h5py gives str or bytes; None: ``default``)."""
    if value is None:
        return default
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    return str(value)


def json_attr(attrs: h5py.AttributeManager, name: str) -> Any:
    """The JSON attribute ``name`` decoded (None when absent; ValueError naming the attribute
    when it is not JSON)."""
    raw = attrs.get(name)
    try:
        return None if raw is None else json.loads(text(raw))
    except ValueError as err:
        raise ValueError(f"attribute {name!r} is not JSON ({err})") from err
    except RecursionError:  # the decoder recurses per level
        raise ValueError(f"attribute {name!r} is not JSON this reader takes (nested too deeply)") from None


@contextmanager
def naming(obj: h5py.Group | h5py.Dataset) -> Iterator[None]:
    """Errors reading `obj` (a member missing, a value or JSON attribute malformed) as a
    ValueError that names its HDF5 path: '/points/0001/table/strain: ... 'fx' ...'."""
    try:
        yield
    except (KeyError, ValueError, TypeError) as err:
        raise ValueError(f"{obj.name}: {err}") from err


def stored_values(ds: h5py.Dataset) -> npt.NDArray[Any]:
    """The values of dataset `ds`; complex from either layout: run.h5's (h5py's members r, i)
    or the h5 export's (members real, imag)."""
    data = ds[()]
    names = getattr(data, "dtype", np.dtype(float)).names
    if names is not None and set(names) == {"real", "imag"}:
        out: npt.NDArray[np.complex128] = np.empty(data.shape, np.complex128)
        out.real, out.imag = data["real"], data["imag"]
        return out
    return np.asarray(data)


def open_h5(path: Path) -> h5py.File:
    """``path`` opened for reading; RunDirError when it is not a readable HDF5 file."""
    import h5py

    try:
        return h5py.File(path, "r")
    except OSError as err:
        raise RunDirError(path, f"not a readable HDF5 file ({err})") from err
