"""The closing table of `orbitrig sweep`: the identified coefficients of every complete point.

In a --sim run each point also carries the simulator's truth (orbitrig.run.truth): its
impedance Z(Omega) per orbit frequency and the constant K, C, D best fitting it over the
point's orbit speeds. The coefficient errors compare against that constant best fit; the
impedance error compares the identified model's Z with the true Z at every frequency.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

#: above this many complete points the final table is one summary row per point
DETAIL_POINTS = 4
_COEF_UNIT = {"K": "N/m", "C": "N s/m", "D": "kg"}
TRUE_NOTE = ("true = the constant K, C, D best fitting the simulator's true Z(Omega) over the point's "
             "orbit speeds; (%) = |identified - true| / largest true entry of the matrix")  # fmt: skip
Z_NOTE = ("|dZ|/|Z| = worst over the orbit frequencies of |Z_identified - Z_true| / |Z_true| "
          "(Frobenius norms; Z_true the simulator's impedance)")  # fmt: skip


def compare_with_truth(coefficients: dict, truth: dict) -> dict[str, float]:
    """Error of each constant-term K, C, D entry against the truth's constant best fit
    (K0, C0, D0), in percent of the largest true entry of its matrix."""
    out = {}
    for m in "KCD":
        true = truth.get(f"{m}0")
        if true is None:
            continue
        scale = max(abs(v) for row in true for v in row) or 1.0
        for i, a in enumerate("xy"):
            for j, b in enumerate("xy"):
                key = f"{m}{a}{b}"
                if key in coefficients and coefficients[key] is not None:
                    out[key] = abs(coefficients[key] - true[i][j]) / scale * 100.0
    return out


def worst_impedance_error(result: dict, truth: dict | None) -> float | None:
    """Worst |Z_identified - Z_true| / |Z_true| over the truth's frequencies, percent
    (None without a true impedance)."""
    from orbitrig.run.truth import impedance_deviation

    if not truth or "Z_re" not in truth:
        return None
    return float(np.max(impedance_deviation(result, truth))) * 100.0


def fit_label(ident) -> str:
    """'piezo kcd11 ols', 'strain kcd11 power:1 ols' (a StoredIdentification)."""
    fd = "" if ident.freq_dep == "none" else f" {ident.freq_dep}"
    return f"{ident.lms} {ident.model}{fd} {ident.method}"


def print_coefficients(out: Path) -> None:
    """Identified constant-term coefficients of every complete point, beside the truth in --sim mode."""
    from rich.console import Console

    from orbitrig.store.reader import read_run

    console = Console()
    complete = read_run(out).complete_points
    if len(complete) > DETAIL_POINTS:
        _print_summary(console, complete, out)
        return
    for point in complete:
        _print_point(console, point)


def _print_point(console, point) -> None:
    from rich.table import Table

    from orbitrig.store.csvfile import coef_order

    truth, fits = point.truth, [i for i in point.identifications if i.ok]
    names = sorted({k for i in fits for k in i.result["coefficients"] if "_" not in k}, key=coef_order)
    table = Table(title=f"point {point.name}  {point.settings.label}", title_justify="left")
    table.add_column("coef")
    if truth:
        table.add_column("true", justify="right")
    for ident in fits:
        table.add_column(fit_label(ident), justify="right")
    errs = [compare_with_truth(i.result["coefficients"], truth) if truth else {} for i in fits]
    for c in names:
        row = [c]
        if truth:
            row.append(f"{truth[c[0] + '0']['xy'.index(c[1])]['xy'.index(c[2])]:.4g}")
        for ident, err in zip(fits, errs):
            v = ident.result["coefficients"].get(c)
            row.append(("" if v is None else f"{v:.4g}") + (f" ({err[c]:.1f}%)" if c in err else ""))
        table.add_row(*row)
    z_errs = [worst_impedance_error(i.result, truth) for i in fits]
    if any(e is not None for e in z_errs):
        table.add_row("|dZ|/|Z|", "", *("-" if e is None else f"{e:.2f} %" for e in z_errs))
    console.print(table)
    console.print("units: " + ", ".join(f"{m} {u}" for m, u in _COEF_UNIT.items() if any(c[0] == m for c in names)),
                  markup=False)  # fmt: skip
    if truth:
        console.print(TRUE_NOTE, markup=False)
        if any(e is not None for e in z_errs):
            console.print(Z_NOTE, markup=False)
        top = max(np.abs(truth["orbit"]))
        k, d = (max(abs(v) for row in truth[m] for v in row) for m in ("K0", "D0"))
        console.print(f"D acts as Omega^2 D: at the highest orbit speed that is {100 * top**2 * d / k:.2g} % "
                      "of the largest K entry, so D is weakly determined here", markup=False)  # fmt: skip


def _print_summary(console, complete: list, out: Path) -> None:
    """One row per operating point: the main stiffness and damping entries of the first
    piezo fit; in --sim mode the worst K and C error of every fit and the worst impedance
    error of each point's best-reproducing fit."""
    from rich.table import Table

    table = Table(title=f"{len(complete)} operating points (full tables: coefficients.csv, "
                        f"orbitrig report {out})", title_justify="left")  # fmt: skip
    cols = ("point", "label", "Kxx MN/m", "Kyy MN/m", "Cxx kN s/m", "Cyy kN s/m", "worst K / C error", "|dZ|/|Z|")
    for col in cols:
        table.add_column(col, justify="left" if col in ("point", "label") else "right")
    for point in complete:
        fits = [i for i in point.identifications if i.ok]
        first = next((i.result["coefficients"] for i in fits if i.lms == "piezo"), None)
        row = [point.name, point.settings.label]
        row += [f"{first[c] * scale:.4g}" if first and first.get(c) is not None else "-"
                for c, scale in (("Kxx", 1e-6), ("Kyy", 1e-6), ("Cxx", 1e-3), ("Cyy", 1e-3))]  # fmt: skip
        row += _truth_cells(point.truth, fits)
        table.add_row(*row)
    console.print(table)
    if any(p.truth for p in complete):
        console.print("K / C error: worst over all fits; " + TRUE_NOTE, markup=False)
        console.print(Z_NOTE + "; shown for the fit that reproduces Z best", markup=False)


def _truth_cells(truth: dict | None, fits: list) -> list[str]:
    if not truth:
        return [f"{len(fits)} fits", "-"]
    errs = [compare_with_truth(i.result["coefficients"], truth) for i in fits]
    k = max((e[c] for e in errs for c in e if c[0] == "K"), default=float("nan"))
    c = max((e[c] for e in errs for c in e if c[0] == "C"), default=float("nan"))
    z = [(e, fit_label(i)) for i in fits if (e := worst_impedance_error(i.result, truth)) is not None]
    best = min(z, default=None)
    return [f"{k:.1f} % / {c:.1f} %", "-" if best is None else f"{best[0]:.2f} % ({best[1]})"]
