"""coefficients.csv: one row per (operating point, load measuring system, model).

Every column name states its unit (``spin_rpm``, ``recess_pressure_mpa``, ``Kxx [N/m]``,
``Cxy_1 [N s/m (rad/s)^-1]``, ``residual_rms [N]``); every row is one physical line
(a refusal message that spans lines is joined with ' | '). Numbers are SI except the
settings columns, whose names give their unit. Empty cell: no value (refused model,
or a number the identification could not give). The ``true_*`` columns of a --sim run
are the constant K, C, D best fitting the simulator's true impedance over the point's
orbit speeds (the truth's K0, C0, D0), not coefficients the simulator has.
"""

from __future__ import annotations

import csv
import io
from orbitrig.store.layout import coefficient_si_unit

CSV_HEAD = [
    "point", "label", "spin_rpm", "recess_pressure_mpa", "pressure_ratio", "static_eccentricity",
    "dynamic_eccentricity", "lms", "model", "freq_dep", "method", "n_frequencies", "condition_number",
    "residual_rms [N]", "error",
]  # fmt: skip


def coefficient_column(key: str, kind: str = "") -> str:
    """Column name of coefficient `key`: kind '' -> 'Kxx [N/m]', 'std' -> 'Kxx_std [N/m]', 'true' -> 'true_Kxx [N/m]'."""
    unit = coefficient_si_unit(key)
    if kind == "std":
        return f"{key}_std [{unit}]"
    return f"{'true_' if kind == 'true' else ''}{key} [{unit}]"


def coef_order(key: str) -> tuple:
    """Kxx, Kxy, Kyx, Kyy, Cxx, ..., Dyy, then the Omega^r terms (Kxx_1, ...)."""
    base, _, r = key.partition("_")
    return (int(r) if r.isdigit() else 0, "KCD".find(base[:1]), base[1:], key)


def one_line(text: str) -> str:
    """A message as one CSV line: line breaks become ' | '."""
    return " | ".join(part.strip() for part in str(text).splitlines() if part.strip())


def true_entry(truth: dict, key: str) -> float:
    """True constant-term value of coefficient `key` ('Kxy' ...) at the lowest |Omega|."""
    mat = truth[key[0] + "0"]
    return float(mat["xy".index(key[1])]["xy".index(key[2])])


def _num(v, fmt: str) -> str:
    """A CSV cell: the number in `fmt`, empty for null (the identify JSON's non-finite values)."""
    return "" if v is None else format(float(v), fmt)


def point_rows(point, sim: bool) -> list[dict]:
    """The rows of one complete point (an orbitrig.store.reader.Point)."""
    st = point.settings
    base = {
        "point": point.index, "label": st.label, "spin_rpm": f"{st.spin_rpm:.6g}",
        "recess_pressure_mpa": f"{st.recess_pressure / 1e6:.6g}", "pressure_ratio": f"{st.pressure_ratio:.6g}",
        "static_eccentricity": f"{st.static_eccentricity:.6g}", "dynamic_eccentricity": f"{st.dynamic_eccentricity:.6g}",
    }  # fmt: skip
    truth = point.truth if sim else None
    rows = []
    for ident in point.identifications:
        row = dict(base, lms=ident.lms, model=ident.model, _keys=[])
        d = ident.result
        if d is not None:
            row.update({"freq_dep": d["freq_dep"], "method": d["method"], "n_frequencies": d["n_frequencies"],
                        "condition_number": _num(d["condition_number"], ".6g"),
                        "residual_rms [N]": _num(d["residual_rms"], ".6g"), "error": ""})  # fmt: skip
            for k, v in d["coefficients"].items():
                row[coefficient_column(k)] = _num(v, ".8g")
                row[coefficient_column(k, "std")] = _num((d.get("std_errors") or {}).get(k), ".6g")
            row["_keys"] = list(d["coefficients"])
        else:
            row.update(freq_dep=ident.freq_dep, method=ident.method, error=one_line(ident.error or ""))
        if truth is not None:
            for k in (k for k in row["_keys"] if "_" not in k):
                row[coefficient_column(k, "true")] = f"{true_entry(truth, k):.8g}"
        rows.append(row)
    return rows


def columns(rows: list[dict]) -> list[str]:
    """CSV_HEAD, then each coefficient and its standard error, then the true values."""
    keys: list[str] = []
    for r in rows:
        keys += [k for k in r["_keys"] if k not in keys]
    keys.sort(key=coef_order)
    cols = CSV_HEAD + [c for k in keys for c in (coefficient_column(k), coefficient_column(k, "std"))]
    true = [k for k in keys if "_" not in k and any(coefficient_column(k, "true") in r for r in rows)]
    return cols + [coefficient_column(k, "true") for k in true]


def render(rows: list[dict]) -> bytes:
    """The whole file's bytes (UTF-8, header + one line per row)."""
    return render_table(columns(rows), rows)


def render_table(fieldnames: list[str], rows: list[dict]) -> bytes:
    """A coefficients-layout CSV's bytes: the header `fieldnames`, one line per row (missing
    cells empty, keys not in `fieldnames` ignored). The one writer of coefficients.csv and of
    `orbitrig reduce`'s file; write the bytes with orbitrig.store.durable.write_atomic."""
    buf = io.StringIO(newline="")
    w = csv.DictWriter(buf, fieldnames=fieldnames, restval="", extrasaction="ignore", lineterminator="\n")
    w.writeheader()
    w.writerows(rows)
    return buf.getvalue().encode("utf-8")
