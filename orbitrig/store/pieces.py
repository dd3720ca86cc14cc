"""HDF5 content of the durable pieces, which is also the content of the consolidated run.h5.

A block file's root is exactly the group ``/points/PPPP/frequencies/FF_dir`` of run.h5,
and a results file's root holds the point's ``table``, ``identification``, ``truth``,
``lms_comparison`` and ``runout_turns``; consolidation copies them unchanged. Every dataset carries a
``units`` attribute; channel, coefficient and column names are string datasets or
attributes, so MATLAB's h5read and h5py read everything without parsing JSON.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable
from typing import TYPE_CHECKING, Any

import h5py
import numpy as np
import numpy.typing as npt

from orbitrig.load_systems import LMS
from orbitrig.store.descriptions import (
    DATASETS,
    ORBIT_SIGNED,
    ORBIT_TABLE,
    POWER_FORM,
    SI_PER_COEFFICIENT,
    TRUTH_CONVENTION,
)
from orbitrig.store.annotate import annotate
from orbitrig.store.layout import (
    BLOCK_ATTR_UNITS,
    COHERENCE_PAIRS,
    IDENT_ATTR_UNITS,
    TABLE_ATTR_UNITS,
    U_COLUMNS,
    U_UNITS,
)
from rigunits import COEFFICIENT_UNITS, coefficient_unit
from orbitrig.store.records import BlockChoice, BlockRecord, IdentificationEntry, PointResults

if TYPE_CHECKING:  # annotation only: the store does not import the run wing
    from orbitrig.run.plan import OperatingPoint
    from reduction.table import OrbitTable

STR = h5py.string_dtype()
#: how a stored phasor gives its signal
PHASOR_CONVENTION = "q = Re(q_bar exp(i Omega t))"
IDENT_SCALARS = (
    "n_coefficients",
    "min_frequencies",
    "n_frequencies",
    "condition_number",
    "residual_rms",
    "dof",
    "chi2",
    "p_value",
    "aic",
    "bic",
    "exponent",
)


def to_json(obj: object) -> str:
    """JSON text of plain data that may hold numpy scalars or arrays (e.g. counters, truth)."""
    return json.dumps(obj, default=lambda o: o.tolist() if isinstance(o, (np.generic, np.ndarray)) else str(o))


def strings(values: Iterable[str]) -> npt.NDArray[np.object_]:
    """Text for an attribute (variable-length UTF-8)."""
    return np.array(list(values), dtype=STR)


def fixed_text(values: Iterable[object]) -> npt.NDArray[np.bytes_]:
    """Text for a dataset: fixed-length UTF-8 bytes in HDF5's ASCII string type (GNU Octave's
    load reads neither variable-length strings nor the UTF-8 string type); h5py reads it with
    ``.asstr("utf-8")`` (a bare ``.asstr()`` refuses bytes outside ASCII)."""
    encoded = [str(v).encode("utf-8") for v in values]
    return np.array(encoded, dtype=f"S{max([1, *map(len, encoded)])}")


def put(g: h5py.Group, name: str, data: npt.ArrayLike, units: str, **attrs: object) -> h5py.Dataset:
    """A dataset with its units (and other attributes)."""
    if isinstance(data, np.ndarray) and data.dtype == STR:
        data = fixed_text(data)
    ds = g.create_dataset(name, data=data)
    ds.attrs["units"] = units
    for k, v in attrs.items():
        ds.attrs[k] = v
    return ds


def point_settings(point: OperatingPoint, software: str = "") -> dict[str, Any]:
    """The attributes of a point (point.json and /points/PPPP in run.h5), SI; ``software``: the
    software that measures it (a resumed run's points may come from more than one)."""
    return {
        "software": software,
        "index": point.index,
        "spin": point.spin,
        "spin_rpm": point.spin_rpm,
        "recess_pressure": point.recess_pressure,
        "pressure_ratio": point.pressure_ratio,
        "static_eccentricity": point.static_eccentricity,
        "dynamic_eccentricity": point.dynamic_eccentricity,
        "orbit_radius": point.orbit_radius,
        "label": point.label,
    }


def write_block(g: h5py.Group, rec: BlockRecord, channels: list[str], units: list[str]) -> None:
    """One orbit frequency: settings as attributes, the measurement as datasets with units."""
    b = rec.block
    chan = strings(channels)
    per_channel = " or ".join(dict.fromkeys(units)) + " per channel (see channel_units)"
    a = g.attrs
    a.update(
        {
            "orbit": b.orbit,
            "orbit_hz": b.orbit_hz,
            "direction": b.direction,
            "measured_orbit_speed": rec.measured_orbit_speed,
            "spin_written": rec.written[0],
            "orbit_written": rec.written[1],
            "stop_reason": str(rec.stop_reason),  # the plain word: h5py stores no str subclass (daq StopReason)
            "n_records": int(rec.n_records if rec.n_records is not None else len(rec.raw_counts)),
            "complete": True,
            "units_of_attributes": BLOCK_ATTR_UNITS,
        }
    )
    a["channels"], a["channel_units"] = chan, strings(units)
    _write_signals(g, rec, per_channel)
    _write_phasors(g, rec, per_channel)
    st = g.create_group("stats")
    for k, v in rec.stats.items():
        st.attrs[k] = to_json(v) if isinstance(v, (dict, list)) else v
    if rec.choice is not None:
        write_choice(g.create_group("sequential"), rec.choice)
    annotate(g)


def _write_signals(g: h5py.Group, rec: BlockRecord, per_channel: str) -> None:
    """A block's samples: raw counts, their slots, the channels' calibration, the synchronous
    average and what is left of each revolution around it."""
    put(g, "raw_counts", np.asarray(rec.raw_counts, dtype=np.int16), "count", dimensions="revolution, channel, sample")
    put(
        g,
        "slots",
        np.asarray(rec.slots, dtype=np.int16),
        "slot (1/360 of an orbit revolution after the trigger)",
        dimensions="channel, sample",
    )
    put(g, "gains", np.asarray(rec.gains, dtype=np.float64), per_channel.replace("per", "/count per"))
    put(g, "offsets", np.asarray(rec.offsets, dtype=np.float64), per_channel)
    put(
        g,
        "mean",
        np.asarray(rec.mean, dtype=np.float64),
        per_channel,
        dimensions="channel, sample",
        meaning="synchronous average over the revolutions",
    )
    put(g, "dc", np.asarray(rec.dc, dtype=np.float64), per_channel)
    put(g, "rms_residual", np.asarray(rec.rms_residual, dtype=np.float64), per_channel)


def _write_phasors(g: h5py.Group, rec: BlockRecord, per_channel: str) -> None:
    """A block's phasors: per revolution and averaged (with their uncertainty), the revolutions
    averaged and the coherence of each displacement-force pair."""
    put(
        g,
        "record_phasors",
        np.asarray(rec.record_phasors, dtype=np.complex128),
        per_channel,
        dimensions="revolution, channel",
        convention=PHASOR_CONVENTION,
    )
    put(
        g,
        "phasors",
        np.asarray(rec.phasors, dtype=np.complex128),
        per_channel,
        convention=PHASOR_CONVENTION,
    )
    if rec.revolutions is not None:
        put(
            g,
            "revolutions",
            np.asarray(rec.revolutions, dtype=np.int64),
            "1",
            dimensions="revolution",
            meaning="the A/D board's revolution number of each averaged revolution (gaps: dropped ones)",
        )
    if rec.uncertainty is not None:
        t = rec.uncertainty_turns
        turns = {} if t is None else {"spin_turns": t.used, "spin_turns_basis": t.basis.value}
        put(
            g,
            "uncertainty",
            np.asarray(rec.uncertainty, dtype=np.float64),
            per_channel,
            meaning="standard uncertainty of each averaged phasor",
            **turns,
        )
    put(
        g,
        "coherence",
        np.asarray(rec.coherence, dtype=np.float64),
        "1",
        rows=strings(LMS),
        columns=strings(COHERENCE_PAIRS),
        meaning="gamma^2 between displacement and force",
    )


def write_choice(g: h5py.Group, c: BlockChoice) -> None:
    """A sequential point's decision: why, what (ratio, direction, revolutions, seconds), the rig
    seconds spent before it, and each coefficient's predicted relative standard error before and
    after it (fractions of the coefficient's scale)."""
    g.attrs.update(
        {
            "reason": c.reason,
            "ratio": math.nan if c.ratio is None else c.ratio,
            "whirl": str(c.direction),  # a plain str: h5py stores no str subclass
            "revolutions": c.revolutions,
            "seconds": c.seconds,
            "spent_s": c.spent_s,
        }
    )
    g.create_dataset("coefficient_names", data=fixed_text(c.coefficients))
    put(
        g,
        "before",
        np.asarray(c.before, dtype=np.float64),
        "1",
        meaning="predicted relative standard error (standard error / scale) of each coefficient before the decision",
    )
    put(g, "after", np.asarray(c.after, dtype=np.float64), "1", meaning="the same, predicted after the chosen block")


def write_results(g: h5py.Group, res: PointResults) -> None:
    """A point's orbit tables, identifications, the simulator's truth and the LMS comparison."""
    tg = g.create_group("table")
    for lms, t in res.tables.items():
        _write_table(tg.create_group(lms), t)
    ig = g.create_group("identification")
    for (lms, key), entry in res.identifications.items():
        _write_identification(ig.create_group(f"{lms}__{key}"), entry)
    if res.truth is not None:
        write_truth(g.create_group("truth"), res.truth)
    g.create_group("lms_comparison").attrs["json"] = to_json(res.lms_comparison)
    if res.runout_turns is not None:
        g.create_group("runout_turns").attrs["json"] = to_json(res.runout_turns)
    if res.sequential is not None:
        write_choice(g.create_group("sequential"), res.sequential)
    annotate(g)


def _write_table(h: h5py.Group, t: OrbitTable) -> None:
    h.attrs["spin"] = t.spin
    h.attrs["units_of_attributes"] = TABLE_ATTR_UNITS
    put(h, "orbit", np.asarray(t.orbit, dtype=np.float64), "rad/s", meaning=ORBIT_TABLE)
    put(h, "orbit_hz", np.asarray(t.orbit_hz, dtype=np.float64), "Hz")
    meanings = (
        ("m", "x displacement"),
        ("m", "y displacement"),
        ("N", "x force on the journal"),
        ("N", "y force on the journal"),
    )
    for (name, z), (unit, what) in zip(t.phasors.items(), meanings):
        put(h, name, np.asarray(z, dtype=np.complex128), unit, meaning=what, convention=PHASOR_CONVENTION)
    if t.gamma2 is not None:
        put(h, "gamma2", np.asarray(t.gamma2, dtype=np.float64), "1", columns=strings(COHERENCE_PAIRS))
    if t.n_records is not None:
        put(h, "n_records", np.asarray(t.n_records, dtype=np.int64), "1")
    if t.u is not None:
        put(
            h,
            "u",
            np.asarray(t.u, dtype=np.float64),
            ", ".join(U_UNITS),
            columns=strings(U_COLUMNS),
            meaning="standard uncertainty of each averaged phasor",
        )


def _float(v: Any) -> float:
    return math.nan if v is None else float(v)


def _write_identification(h: h5py.Group, entry: IdentificationEntry) -> None:
    spec = entry["spec"]
    h.attrs.update(
        {
            "model": spec.model,
            "freq_dep": spec.freq_dep,
            "method": str(spec.method),  # a plain str, as the whirl above
            "units_of_attributes": IDENT_ATTR_UNITS,
        }
    )
    if "json" not in entry:
        h.attrs["error"] = entry["error"]
        return
    d = entry["json"]
    h.attrs["json"] = to_json(d)
    for k in IDENT_SCALARS:
        if k in d and (d[k] is None or isinstance(d[k], (int, float))):
            h.attrs[k] = _float(d[k])
    names = list(d["coefficients"])
    h.create_dataset("names", data=fixed_text(names))
    h.create_dataset("units", data=fixed_text(coefficient_unit(k) for k in names))
    unit = SI_PER_COEFFICIENT
    put(h, "coefficients", np.array([_float(d["coefficients"][k]) for k in names]), unit)
    std = d.get("std_errors") or {}
    put(h, "std_errors", np.array([_float(std.get(k)) for k in names]), unit, meaning="one standard deviation")
    _write_intervals(h, d, names, unit)
    if d.get("free") and d.get("covariance") is not None:
        free = list(d["free"])
        cov = np.array([[_float(v) for v in row] for row in d["covariance"]], dtype=np.float64).reshape(len(free), -1)
        put(h, "covariance", cov, "SI: product of the two coefficients' units", names=strings(free))
    for k in ("notes", "warnings"):
        h.create_dataset(k, data=fixed_text(d.get(k) or []))
    from orbitrig.store.fit_analysis import write_fit_analysis  # it uses put/strings of this module

    write_fit_analysis(h, d, names)


def _write_intervals(h: h5py.Group, d: dict[str, Any], names: list[str], unit: str) -> None:
    """``interval_95``: value -+ U (orbitrig.store.fit_record.coverage_interval), its basis in the
    group's attribute ``interval_95_basis``; ``interval_95_statistical``: the fit's confidence_95."""
    from orbitrig.store.fit_record import coverage_interval  # it imports this module's layout

    lo_hi, basis = coverage_interval(d)
    h.attrs["interval_95_basis"] = basis
    columns = strings(("low", "high"))
    data = np.array([lo_hi[k] for k in names], dtype=np.float64).reshape(-1, 2)
    put(h, "interval_95", data, unit, columns=columns, meaning=f"value -+ U, U = k x {basis} standard uncertainty")
    ci = d.get("confidence_95")
    if ci:
        stat = np.array([[_float(v) for v in (ci.get(k) or (None, None))] for k in names]).reshape(-1, 2)
        put(h, "interval_95_statistical", stat, unit, columns=columns, meaning="two-sided 95 %, statistical only")


def write_truth(h: h5py.Group, truth: dict[str, Any]) -> None:
    """The simulator's truth of a point (orbitrig.run.truth): the JSON in attribute ``json``
    and, when the truth holds the true impedance, numeric datasets with units: ``orbit``,
    ``orbit_hz``, ``Z`` (row, 2, 2) and the best fits under ``fits/constant`` and ``fits/power``."""
    h.attrs["json"] = to_json(truth)
    if "Z_re" not in truth:
        return
    h.attrs["meaning"] = str(truth.get("definition", "the simulator's truth"))
    put(h, "orbit", np.asarray(truth["orbit"], dtype=np.float64), "rad/s", meaning=ORBIT_SIGNED)
    put(h, "orbit_hz", np.asarray(truth["orbit_hz"], dtype=np.float64), "Hz")
    z = np.asarray(truth["Z_re"], dtype=np.float64) + 1j * np.asarray(truth["Z_im"], dtype=np.float64)
    put(
        h,
        "Z",
        z.reshape(-1, 2, 2),
        "N/m",
        dimensions="orbit row, force (fx, fy), displacement (x, y)",
        convention=TRUTH_CONVENTION,
    )
    fits = h.create_group("fits")
    put(fits, "band", np.asarray(truth["band"], dtype=np.float64), "rad/s", meaning="|Omega| the fits use")
    const = fits.create_group("constant")
    for m in "KCD":
        put(const, m, np.asarray(truth["fits"]["constant"][m], dtype=np.float64), COEFFICIENT_UNITS[m])
    power = fits.create_group("power")
    exps = dict(zip("mnp", truth["fits"]["power"]["exponents"]))
    power.attrs["exponents"] = np.asarray(list(exps.values()), dtype=np.int64)
    power.attrs["form"] = POWER_FORM
    for k in ("K0", "Km", "C0", "Cn", "D0", "Dp"):  # units: orbitrig.store.descriptions ({m}: the exponent)
        put(power, k, np.asarray(truth["fits"]["power"][k], dtype=np.float64), DATASETS[k][0].format(**exps))
