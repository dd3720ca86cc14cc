"""``orbitrig export --format mat``: run.mat (MATLAB 5, scipy.io.savemat; GNU Octave loads it).

``run`` (provenance, channels), ``units`` (the unit of every field of one unit, each a unit
pint parses: the settings, the load systems' fields such as ``gamma2_xfx`` ... ``gamma2_yfy``,
truth's, ``theta``, a fit's ``residual_rms`` (N), ``n_frequencies``, ``condition_number``, ``e_n``,
``dof`` ..., the point's ``index``, the run's ``sim``), ``unit_rules`` (in words: the fields whose unit differs per entry,
and the conventions), and ``points.pPPPP`` per complete
point: the settings with ``settings_units``; per load measuring system the orbit table
(complex ``x``, ``y``, ``fx``, ``fy``, ``direction``, ...) with ``units``;
``identification.<lms>__<model>__<freq_dep>__<method>`` per fit (``names``, ``units``,
``coefficients``, ``std_errors``, ``U``, ``interval_95`` (value -+ U, its basis in
``interval_95_basis``: combined | statistical only), ``interval_95_statistical`` (the fit's
statistical-only 95 % interval), ``covariance`` with
``covariance_names``, the budget ``statistical`` ... ``expanded``, ``n_frequencies``,
``condition_number``, ``residual_rms``, the goodness of fit ``dof``, ``chi2``, ``p_value``, ``aic``,
``bic`` (where the fit gives them), ``interval`` (normal | student_t, text),
``confidence_level`` (of interval_95_statistical) and ``k`` (the coverage factor of U), ``adequacy_*``
(numbers; ``adequacy_verdict``, ``adequacy_test``, ``adequacy_constant`` text), ``e_n``,
``derived`` with ``derived_units`` (also ``c_eff_zero_xx``, ``c_eff_zero_yy``: Omega_0 and its
std, rad/s, where C_eff changes sign) and ``derived_covariance`` (combined | statistical),
``error``, ``notes``, ``warnings``); ``truth``
(--sim), ``waveforms.bFF_dir`` (``mean`` and ``theta`` (channel x sample), ``dc``,
complex ``phasors``, ``uncertainty``, ``orbit_hz``, ``direction``, ``n_records``) and
``runout_turns`` (one entry per block in the orbit table's row order: ``orbit_hz``,
``direction``, the spin turns per board revolution ``commanded``, ``fitted``, its ``u``,
``resolved`` (uint8), ``used``, and ``unfitted`` (a cell of texts); export_content.RUNOUT_TURNS)
with ``runout_turns_units`` and ``runout_turns_description``.

Text is a char array (UTF-8 in the file: MATLAB and scipy.io.loadmat read it exactly). GNU
Octave reads such a field by bytes and cuts a text with characters outside ASCII, so each such
text (and each cell array of texts holding one) also has ``<name>_utf8``: its UTF-8 bytes as a
uint8 row (a cell of them); in Octave ``char(m.run.operator_utf8)`` is the exact text.
"""

from __future__ import annotations

import io
import re
from pathlib import Path
from typing import Any

import numpy as np

from orbitrig.store import export_content as content
from orbitrig.store.descriptions import ATTRIBUTES, DATASETS, POWER_FORM, TRUTH_CONVENTION
from orbitrig.store.durable import write_atomic
from orbitrig.store.errors import StorageError
from orbitrig.store.fit_record import point_fits
from orbitrig.store.layout import U_COLUMNS, U_UNITS

#: ``units`` beside the load systems' fields: the settings, theta and the phasors' orbit speed,
#: a fit's single values and E_n, the point's index and the run's sim flag (their units as
#: run.h5 states them: orbitrig.store.descriptions)
BASE_UNITS = {
    **content.SETTINGS,
    "orbit": "rad/s",
    "theta": "rad",
    **{k: u for k, (u, _) in content.FIT_QUALITY.items() if u},  # dof, chi2, ..., k (of U); interval: text
    **{f"adequacy_{k}": "1" for k in content.ADEQUACY_NUMBERS},
    **{k: ATTRIBUTES[k][0] for k in ("n_frequencies", "condition_number", "residual_rms", "index", "sim")},
    "e_n": DATASETS["e_n"][0],
    "expanded_k": "1",  # each coefficient's k of U, aligned with names (k: the largest)
}
#: ``unit_rules``: the fields whose unit differs per entry, and the conventions
UNIT_RULES = {
    "coefficients": "per coefficient: identification.*.units (also std_errors, U, interval_95*, the budget, truth)",
    "covariance": "entry (i, j) in units(i) x units(j), over covariance_names",
    "mean": "per channel: run.channel_units (also dc, phasors, uncertainty)",
    "convention": "phasors q = Re(q_bar exp(i theta)); forces on the journal, f_bar = -Z d_bar; orbit of a load "
    "system's table: |Omega| > 0 (the whirl: direction, +1 forward, -1 backward); truth.orbit: signed (< 0 backward)",
    "truth": f"truth.Z: {TRUTH_CONVENTION}; truth.power_*: {POWER_FORM}",
    "text": "a text (or cell of texts) with characters outside ASCII also as <name>_utf8, its UTF-8 bytes "
    "(uint8 row; a cell of them): GNU Octave cuts such a char field, char(<name>_utf8) is the exact text",
}
#: the suffix of a text's UTF-8 bytes field
UTF8 = "_utf8"


def field(name: str) -> str:
    """A MATLAB struct field name: letters, digits, '_', starting with a letter, <= 63 chars."""
    name = re.sub(r"\W", "_", name)
    return (name if name[:1].isalpha() else f"f_{name}")[:63]


def cell(values) -> np.ndarray:
    """A MATLAB cell array of strings."""
    items = [str(v) for v in values]
    arr = np.empty(len(items), dtype=object)
    arr[:] = items
    return arr


def _utf8(text: str) -> np.ndarray:
    """The UTF-8 bytes of ``text`` as a uint8 row."""
    return np.frombuffer(text.encode("utf-8"), dtype=np.uint8).reshape(1, -1)


def add_utf8(struct: dict) -> dict:
    """``struct`` (nested) with ``<name>_utf8`` beside every text, or cell array of texts, that
    holds a character outside ASCII (module docstring)."""
    for key, value in list(struct.items()):
        if isinstance(value, dict):
            add_utf8(value)
            continue
        name = f"{key[: 63 - len(UTF8)]}{UTF8}"
        if isinstance(value, str) and not value.isascii() and name not in struct:
            struct[name] = _utf8(value)
        elif isinstance(value, np.ndarray) and value.dtype == object and name not in struct:
            if any(isinstance(v, str) and not v.isascii() for v in value.flat):
                cells = np.empty(value.size, dtype=object)
                for i, v in enumerate(value.flat):  # one by one: rows of one length would broadcast
                    cells[i] = _utf8(str(v))
                struct[name] = cells.reshape(value.shape)
    return struct


def _fit_struct(fit) -> dict:
    d = content.fit_arrays(fit)
    s = {
        "lms": str(fit.lms),  # a plain str: savemat writes an Enum member as an empty value
        "model": fit.model,
        "freq_dep": fit.freq_dep,
        "method": fit.method,
        "error": fit.error,
        "names": cell(d["names"]),
        "units": cell(d["units"]),
        "coefficients": d["value"],
        "std_errors": d["std"],
        "U": d["U"],
        "interval_95": d.get("interval_95", np.full((len(fit.names), 2), np.nan)),
        "interval_95_statistical": d.get("interval_95_statistical", np.full((len(fit.names), 2), np.nan)),
    }
    if "covariance" in d:
        s["covariance"], s["covariance_names"] = d["covariance"], cell(d["covariance_names"])
    s.update(
        {
            k: v
            for k, v in d.items()
            if k.startswith(("adequacy_", "statistical", "systematic", "combined", "expanded", "e_n"))
            or k in content.FIT_QUALITY
        }
    )
    result = fit.result or {}
    for k in ("n_frequencies", "condition_number", "residual_rms"):
        if k in result:
            s[k] = np.nan if result[k] is None else float(result[k])
    s["notes"], s["warnings"] = cell(d["notes"]), cell(d["warnings"])
    s["not_determined"] = cell(result.get("not_determined") or [])  # names whose U exceeds their magnitude
    if "truth" in d:
        s["truth"] = d["truth"]  # the simulator's truth projected onto this model, aligned with names
    derived = content.derived_columns(fit)
    if derived:
        more = content.derived_properties(fit)
        s["derived_covariance"] = more.pop("covariance", ("", ""))[0]
        s["derived"] = {k: v for k, (v, _) in (derived | more).items()}
        s["derived_units"] = {k: u for k, (_, u) in (derived | more).items()}
    return s


def point_struct(p, channels: list[str], channel_units: list[str]) -> dict:
    settings = content.settings(p)
    s: dict[str, Any] = {k: v for k, (v, _) in settings.items()}
    s.update(index=p.index, label=p.settings.label, settings_units={k: u for k, (_, u) in settings.items()})
    for lms, table in p.tables.items():
        cols = content.table_columns(table)
        t = {"orbit": np.asarray(table.orbit, dtype=float), **table.phasors}
        t.update({k: v for k, (v, _) in cols.items() if not k.endswith(("_re", "_im"))})
        t["units"] = {"orbit": BASE_UNITS["orbit"], **dict(zip(U_COLUMNS, U_UNITS))}
        t["units"] |= {k: u for k, (_, u) in cols.items() if not k.endswith(("_re", "_im"))}
        s[str(lms)] = t
    s["identification"] = {field(f.key): _fit_struct(f) for f in point_fits(p)}
    truth = content.truth_arrays(p.truth)
    if truth:
        s["truth"] = {k: v for k, (v, _) in truth.items()} | {"units": {k: u for k, (_, u) in truth.items()}}
    turns = content.runout_turns_columns(p.runout_turns)
    if turns:  # per block, a legend of its own (as derived)
        s["runout_turns"] = {k: cell(v) if u == "" else v for k, (v, u) in turns.items()}
        s["runout_turns_units"] = {k: u for k, (_, u) in turns.items()}
        s["runout_turns_description"] = {k: content.RUNOUT_TURNS[k][1] for k in turns}
    s["waveforms"] = {
        field(f"b{b['name']}"): {k: v for k, v in b.items() if k != "channels"}
        | {"channels": cell(channels), "channel_units": cell(channel_units)}
        for b in content.waveform_arrays(p, channels)
    }
    return s


def export_mat(run, points: list, out: Path) -> list[Path]:
    from scipy.io import savemat

    structs = {f"p{p.name}": point_struct(p, run.channels, run.channel_units) for p in points}
    tables = [t for pt in structs.values() for t in pt.values() if isinstance(t, dict) and "units" in t]
    data = {
        "run": {
            **content.provenance(run),
            "directory": str(run.directory),
            "sim": bool(run.sim),
            "channels": cell(run.channels),
            "channel_units": cell(run.channel_units),
        },
        "units": BASE_UNITS | {k: u for t in tables for k, u in t["units"].items()},  # the fields' own units
        "unit_rules": UNIT_RULES,
        "points": structs,
    }
    buf = io.BytesIO()
    try:
        savemat(buf, add_utf8(data), long_field_names=True, do_compression=True, oned_as="column")
    except (ValueError, TypeError) as err:
        raise StorageError(out / "run.mat", f"cannot build the MATLAB file: {err}") from err
    path = out / "run.mat"
    write_atomic(path, buf.getvalue())
    return [path]
