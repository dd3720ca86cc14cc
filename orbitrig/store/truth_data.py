"""The simulator's truth of one point (--sim runs) as numpy arrays of stated shapes, SI: what
``RunData.truth`` gives (docs/api.md) and the exports write. The run stores it as JSON
(orbitrig.run.truth: nested lists, run.h5 ``truth`` attribute ``json``); this reads it into arrays once.

n is the number of the point's orbit-table rows, m the number of its |Omega| (``band``). Each
mapping of arrays carries ``units`` (name -> unit, in a form pint parses), as a DataFrame of the
API carries ``attrs["units"]``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from orbitrig.store.descriptions import DATASETS

#: the truth's arrays: name -> (shape, -1 for n or m), unit; per-row K, C, D: some runs stored before the true Z
ARRAYS: dict[str, tuple[tuple[int, ...], str]] = {
    "orbit": ((-1,), "rad/s"),  # signed, < 0 backward: the rows of the orbit table (measured speed)
    "orbit_hz": ((-1,), "Hz"),  # the planned orbit frequency of each row
    "Z_re": ((-1, 2, 2), DATASETS["Z"][0]),  # f_bar = -Z d_bar: rows fx, fy; columns x, y
    "Z_im": ((-1, 2, 2), DATASETS["Z"][0]),
    "band": ((-1,), DATASETS["band"][0]),
    **{m: ((-1, 2, 2), DATASETS[m][0]) for m in "KCD"},
    **{k: ((2, 2), DATASETS[k][0]) for k in ("K0", "C0", "D0")},
}
#: the power form's terms and the exponent that names each one's unit (orbitrig.store.descriptions)
POWER_TERMS = {"K0": None, "Km": "m", "C0": None, "Cn": "n", "D0": None, "Dp": "p"}


def _array(value: Any, shape: tuple[int, ...]) -> np.ndarray:
    """``value`` (nested lists, null for NaN) as a float array of ``shape``; ValueError when it is not one."""
    return np.asarray(value, dtype=float).reshape(shape)  # None -> nan


def _fits(fits: Mapping[str, Any]) -> dict[str, Any]:
    """The best fits of Z over the band: ``constant`` K, C, D and ``power`` (Eq. 15), each (2, 2) with units."""
    out: dict[str, Any] = dict(fits)
    if "constant" in fits:
        const = {m: _array(v, (2, 2)) for m, v in fits["constant"].items() if m in "KCD"}
        out["constant"] = const | {"units": {m: DATASETS[m][0] for m in const}}
    if "power" in fits:
        exps = dict(zip("mnp", (int(e) for e in fits["power"].get("exponents", ()))))
        power: dict[str, Any] = {k: _array(v, (2, 2)) for k, v in fits["power"].items() if k in POWER_TERMS}
        units = {k: DATASETS[k][0].format(**exps) for k in power if POWER_TERMS[k] is None or POWER_TERMS[k] in exps}
        out["power"] = power | {"exponents": tuple(exps.values()), "units": units}
    return out


def truth_data(truth: Mapping[str, Any] | None) -> dict[str, Any] | None:
    """The stored truth of a point as arrays (ARRAYS: ``orbit`` (n,) rad/s, ``Z_re``, ``Z_im``
    (n, 2, 2) N/m, ``K0``, ``C0``, ``D0`` (2, 2) N/m, N s/m, kg, ...), ``fits`` likewise, ``units``;
    ``definition`` and any other entry as stored. None without a truth."""
    if truth is None:
        return None
    out: dict[str, Any] = dict(truth)
    arrays = {k: _array(truth[k], shape) for k, (shape, _) in ARRAYS.items() if k in truth}
    out |= arrays
    if isinstance(truth.get("fits"), Mapping):
        out["fits"] = _fits(truth["fits"])
    out["units"] = {k: ARRAYS[k][1] for k in arrays}
    return out
