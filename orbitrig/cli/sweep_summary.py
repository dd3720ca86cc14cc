"""The sweep's closing summary: identified coefficients of every complete point (beside the
simulator's truth in --sim runs) with their expanded uncertainty, then every refused model,
every warning, the model-adequacy verdicts and the two load measuring systems' consistency.

In --sim runs the truth is the simulator's impedance Z(Omega) per orbit frequency
(orbitrig.run.truth): each fit's coefficient errors compare with its own truth, that Z
projected onto the fit's model (orbitrig.run.model_truth); `|dZ|/|Z|` compares each fit's
Z with the true Z. A coefficient whose expanded uncertainty exceeds its magnitude is
marked "not determined".

Read from the run directory with orbitrig.store.reader.read_run (works also when the
consolidated run.h5 could not be written)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from orbitrig.cli.plain_table import OutputFormat, PlainTable, Transcript
from orbitrig.analysis.rounding import at_decimals, number, uncertainty_decimals, with_uncertainty
from orbitrig.analysis.run_warnings import fit_warnings
from orbitrig.analysis.warning_groups import point_ranges, warning_lines
from orbitrig.load_systems import LoadSystem
from orbitrig.run.point_report import judgement_lines
from orbitrig.store.csvfile import coef_order, fit_truth
from orbitrig.store.layout import MATRIX_NAMES
from orbitrig.store.layout import point_cell
from orbitrig.store.reader import freq_dep_key, read_run, read_run_points
from orbitrig.store.stored_run import Point
from reduction.statistics import CHI2_ALPHA
from rigunits import DISPLAY_UNITS, display_unit

#: above this many complete points the final table is one summary row per point
DETAIL_POINTS = 4
#: the terms of the summary row: the main stiffness and damping entries
MAIN_TERMS = ("Kxx", "Kyy", "Cxx", "Cyy")
TRUE_NOTE = (
    "true = the simulator's true Z(Omega) projected onto each fit's model (its constraints, "
    "frequency dependence, frequencies and weights); (%) = |identified - true| / largest true entry "
    "of the matrix; const. fit = the constant K, C, D best fitting the true Z over the point's orbit "
    "speeds"
)
D_NOTE = (
    f"D = {MATRIX_NAMES['D']}: it absorbs whatever grows with Omega^2, not only the fluid's "
    "inertia (e.g. the recesses' compressibility, an uncorrected delay of the measuring chain)"
)
ND_NOTE = "n.d. = not determined: the expanded uncertainty U exceeds the magnitude"
Z_NOTE = (
    "|dZ|/|Z| = worst over the orbit frequencies of |Z_identified - Z_true| / |Z_true| "
    "(Frobenius norms; Z_true the simulator's impedance)"
)

REJECTED_NOTE = (
    f"* the fit's chi2 adequacy test rejects it (p < {CHI2_ALPHA:g}): the residuals exceed the stated uncertainties"
)
REJECTED_COUNT_NOTE = (
    f"rejected * = fits the chi2 adequacy test rejects (p < {CHI2_ALPHA:g}): their residuals "
    "exceed the stated uncertainties"
)


def rejected(d: dict) -> bool:
    """Does the chi2 adequacy test reject this stored fit (p below CHI2_ALPHA)?"""
    p = d.get("p_value")
    return isinstance(p, (int, float)) and p < CHI2_ALPHA


def compare_with_truth(d: dict, truth: dict) -> dict[str, float]:
    """Error of each constant-term K, C, D entry of stored fit ``d`` against its truth
    (csvfile.fit_truth), in percent of the largest true entry of its matrix."""
    true, coefficients, out = fit_truth(d, truth), d["coefficients"], {}
    for m in "KCD":
        keys = [f"{m}{a}{b}" for a in "xy" for b in "xy" if f"{m}{a}{b}" in true]
        scale = max((abs(true[k]) for k in keys), default=0.0) or 1.0
        for key in keys:
            if coefficients.get(key) is not None:
                out[key] = abs(coefficients[key] - true[key]) / scale * 100.0
    return out


def worst_impedance_error(result: dict, truth: dict | None) -> float | None:
    """Worst |Z_identified - Z_true| / |Z_true| over the truth's frequencies, percent
    (None without a true impedance)."""
    from orbitrig.run.truth import impedance_deviation

    if not truth or "Z_re" not in truth:
        return None
    return float(np.max(impedance_deviation(result, truth))) * 100.0


def best_impedance_error(fits, truth: dict | None) -> str:
    """The summary cell: the smallest worst-frequency |dZ|/|Z| of the fits ('-' without truth Z)."""
    errs = [e for d in fits if (e := worst_impedance_error(d, truth)) is not None and np.isfinite(e)]
    return f"{min(errs):.2f} %" if errs else "-"


def _fits(p: Point) -> dict[str, dict]:
    """Stored JSON of every fit that gave coefficients, by storage key (lms__model__fd__method)."""
    return {
        f"{i.lms}__{i.model}__{freq_dep_key(i.freq_dep)}__{i.method}": i.result
        for i in p.identifications
        if i.result is not None
    }


def _judged(p: Point) -> list[tuple[LoadSystem, str, dict | None, str | None]]:
    return [(i.lms, f"{i.model} {i.freq_dep} {i.method}", i.result, i.error) for i in p.identifications]


def _uncertainty(d: dict, key: str) -> float | None:
    """Expanded uncertainty of `key` as stored with the fit (run.point_analysis; its k: fit_record.expanded_ks)."""
    return ((d.get("expanded_uncertainty") or {}).get("values") or {}).get(key)


def _decimals(d: dict, key: str) -> int | None:
    """The decimal `key` of fit `d` is shown to in its display unit: that of its U to 2
    significant digits (rounding.uncertainty_decimals; None without U: 4 significant digits)."""
    u = _uncertainty(d, key)
    return uncertainty_decimals(None if u is None else u * display_unit(key)[1])


def _summary_cells(p: Point) -> list[str]:
    """Adequacy, LMS consistency and warnings/refusals of one point, for the summary row."""
    fits = _fits(p).values()
    verdicts = [d["adequacy"]["supported"] for d in fits if "supported" in (d.get("adequacy") or {})]
    worst = [
        d["lms_consistency"]["max_abs"] for d in fits if (d.get("lms_consistency") or {}).get("max_abs") is not None
    ]
    warnings = sum(len(d.get("warnings") or []) for d in fits)
    refused = sum(1 for i in p.identifications if not i.ok)
    nd = sum(len(d.get("not_determined") or []) for d in fits)
    return [
        f"{sum(verdicts)} of {len(verdicts)} yes" if verdicts else "-",
        f"{max(worst):.2g}" if worst else "-",
        str(nd),
        f"{sum(rejected(d) for d in fits)} of {len(fits)}",
        f"{warnings} / {refused}",
    ]


def rejected_lines(complete: list[Point]) -> list[str]:
    """Per fit family the chi2 adequacy test rejects somewhere: which systems, at how many
    of its points and which ('kc7 none ols, piezo, strain: at 5 of 6 points (0000-0004)')."""
    families: dict[str, dict] = {}
    for p in complete:
        for i in p.identifications:
            if i.result is not None:
                f = families.setdefault(f"{i.model} {i.freq_dep} {i.method}", {"all": set(), "at": set(), "lms": set()})
                f["all"].add(int(p.name))
                if rejected(i.result):
                    f["at"].add(int(p.name))
                    f["lms"].add(i.lms)
    return [
        f"{fit}, {', '.join(sorted(f['lms']))}: at {len(f['at'])} of {len(f['all'])} points ({point_ranges(f['at'])})"
        for fit, f in sorted(families.items())
        if f["at"]
    ]


def _print_summary(console: Transcript, complete: list[Point], out: Path, full: bool) -> None:
    """One row per operating point: the main stiffness and damping entries of the first fit
    (piezo), in --sim mode the worst K and C error of every fit, the adequacy verdicts, the
    worst LMS |E_n| and the counts of warnings and refused models. The point is named '0003' in
    text, by its index '3' in CSV and JSON (`full`), as coefficients.csv names it."""
    table = PlainTable(title=f"{len(complete)} operating points (full tables: coefficients.csv, orbitrig report {out})")
    for col in (
        "point",
        "label",
        *(f"{c} {display_unit(c)[0]}" for c in MAIN_TERMS),
        "worst K / C error",
        "|dZ|/|Z|",
        "freq. dep.",
        "LMS |E_n|",
        "n.d.",
        "rejected *",
        "warn / refused",
    ):
        table.add_column(col, justify="left" if col in ("point", "label") else "right")
    for p in complete:
        fits = _fits(p)
        first = next((d for k, d in sorted(fits.items()) if k.startswith(LoadSystem.PIEZO)), None)
        row = [point_cell(p.index, full), p.settings.label]
        row += [_main_cell(first, c) for c in MAIN_TERMS]
        if p.truth:
            errs = [compare_with_truth(d, p.truth) for d in fits.values()]
            k = max((e[c] for e in errs for c in e if c[0] == "K"), default=float("nan"))
            c = max((e[c] for e in errs for c in e if c[0] == "C"), default=float("nan"))
            row += [f"{k:.1f} % / {c:.1f} %", best_impedance_error(fits.values(), p.truth)]
        else:
            row += [f"{len(fits)} fits", "-"]
        table.add_row(*row, *_summary_cells(p))
    console.print(table)
    if any(p.truth for p in complete):
        console.print("K / C error: worst over all fits; " + TRUE_NOTE, markup=False)
        console.print(Z_NOTE + "; of the fit that reproduces Z best", markup=False)
    console.print(
        "freq. dep. = frequency dependence supported by the data (per frequency-dependent fit); "
        "LMS |E_n| = worst normalised piezo - strain difference (the per-point verdict tests all "
        "coefficients at once: chi2 at the 5 % level); "
        "n.d. = coefficients not determined (U > |value|), over all fits; "
        "the stiffness and damping columns to the decimal of their U (2 significant digits)",
        markup=False,
    )
    if lines := rejected_lines(complete):
        console.print(REJECTED_COUNT_NOTE, markup=False)
        for line in lines:
            console.print(f"rejected: {line}", markup=False)
    for p in complete:
        for line in judgement_lines(_judged(p), verdicts=False, brief=True, warnings=False):
            console.print(f"point {p.name}: {line}", markup=False)
    for line in warning_lines(fit_warnings(complete)):  # each warning once per fit family; all in run.log
        console.print(f"warning: {line}", markup=False)


def _main_cell(d: dict | None, c: str) -> str:
    """A summary row's coefficient: to the decimal of its U, as in a point's own table ('-' without it)."""
    if d is None or d["coefficients"].get(c) is None:
        return "-"
    return at_decimals(d["coefficients"][c] * display_unit(c)[1], _decimals(d, c))


def _cell(d: dict, c: str, err: float | None) -> str:
    """'33.79 ± 0.21 (0.4 %)' (in the unit a person reads, rigunits.display_unit: MN/m; U to 2
    significant digits and the value to its decimal, rounding.with_uncertainty, as reduce, the
    report and the dashboard), ' n.d.' appended when not determined; '' without the key."""
    v = d["coefficients"].get(c)
    if v is None:
        return ""
    u, k = _uncertainty(d, c), display_unit(c)[1]
    cell = number(v * k) if u is None else with_uncertainty(v * k, u * k)
    cell += "" if err is None else f" ({err:.1f} %)"
    return cell + (" n.d." if c in (d.get("not_determined") or []) else "")


def _const_cell(truth: dict, c: str, fits: dict[str, dict]) -> str:
    """The constant best fit's `c` in display units, to the finest decimal of the fits' cells
    (their U's), as their 'true' rows: a zero entry reads 0.000, not 7.112e-15; 4 significant
    digits where no fit has a U for it."""
    v = truth[c[0] + "0"]["xy".index(c[1])]["xy".index(c[2])] * display_unit(c)[1]
    places = [n for d in fits.values() if c in d["coefficients"] and (n := _decimals(d, c)) is not None]
    return at_decimals(v, max(places)) if places else number(v)


def _point_table(p: Point) -> tuple[PlainTable, list[str]]:
    """Each coefficient's row (identified ± U (error against the fit's truth)) followed, in
    --sim runs, by a 'true' row (each fit's own truth) beside the constant best fit."""
    fits = _fits(p)
    truth = p.truth
    names = sorted({k for d in fits.values() for k in d["coefficients"] if "_" not in k}, key=coef_order)
    table = PlainTable(title=f"point {p.name}  {p.settings.label}")
    table.add_column("coef")
    if truth:
        table.add_column("const. fit", justify="right")
    for key, d in fits.items():
        table.add_column(key.replace("__none", "").replace("__", " ") + (" *" if rejected(d) else ""), justify="right")
    errs = {k: compare_with_truth(d, truth) for k, d in fits.items()} if truth else {}
    trues = {k: fit_truth(d, truth) for k, d in fits.items()} if truth else {}
    for c in names:
        k = display_unit(c)[1]
        row = [c] + ([_const_cell(truth, c, fits)] if truth else [])
        table.add_row(*row, *(_cell(d, c, errs.get(key, {}).get(c)) for key, d in fits.items()))
        if truth:
            table.add_row(
                "  true",
                "",
                *(
                    ""
                    if c not in trues[f] or c not in d["coefficients"]
                    else at_decimals(trues[f][c] * k, _decimals(d, c))
                    for f, d in fits.items()
                ),
            )
    z_errs = [worst_impedance_error(d, truth) for d in fits.values()]
    if any(e is not None for e in z_errs):
        table.add_row("|dZ|/|Z|", "", *("-" if e is None else f"{e:.2f} %" for e in z_errs))
    return table, names


def print_coefficients(out: Path, fmt: OutputFormat = OutputFormat.TEXT, verified: list[int] | None = None) -> None:
    """Identified constant-term coefficients of every complete point with their expanded
    uncertainty (beside the true ones in --sim mode), then refusals, warnings and verdicts;
    plain tables (every cell in full, split to the terminal's width), CSV or JSON (`fmt`).
    ``verified``: the complete points as the sweep checked them before run.h5 (not hashed again;
    None: every point read and checked here)."""
    console = Transcript()
    if verified is not None:  # the results, not the blocks
        complete = read_run_points(out, verified, blocks=False, verified=True).complete_points
    else:
        complete = read_run(out, blocks=False).complete_points
    if len(complete) > DETAIL_POINTS:
        _print_summary(console, complete, out, full=fmt != OutputFormat.TEXT)
    else:
        _print_points(console, complete)
    console.write(fmt)


def _print_points(console: Transcript, complete: list[Point]) -> None:
    for p in complete:
        table, names = _point_table(p)
        console.print(table)
        console.print(
            "units: " + ", ".join(f"{m} {u}" for m, (u, _) in DISPLAY_UNITS.items() if any(c[0] == m for c in names)),
            markup=False,
        )
        console.print(
            "\u00b1 = expanded uncertainty U (a coverage probability of about 95 %: k = 2, or Student's t at "
            "the effective degrees of freedom where a part of U is estimated from few; coefficients.csv's "
            "KEY_k): statistical (type A) and calibration (type B) combined "
            "(without a stated calibration: statistical only), to 2 significant digits and the value "
            "(and its truth) to the same decimal; " + ND_NOTE,
            markup=False,
        )
        if any(c[0] == "D" for c in names):
            console.print(D_NOTE, markup=False)
        if p.truth:
            _truth_notes(console, p.truth)
        if any(rejected(d) for d in _fits(p).values()):
            console.print(REJECTED_NOTE, markup=False)
        for line in judgement_lines(_judged(p), brief=True):
            console.print(f"point {p.name}: {line}", markup=False)


def _truth_notes(console: Transcript, truth: dict) -> None:
    console.print(TRUE_NOTE, markup=False)
    if "Z_re" in truth:
        console.print(Z_NOTE, markup=False)
    top = max(truth["orbit"], key=abs)
    k, d = (max(abs(v) for row in truth[m] for v in row) for m in ("K0", "D0"))
    console.print(
        f"D acts as Omega^2 D: at the highest orbit speed that is {100 * top**2 * d / k:.2g} % "
        "of the largest K entry, so D is weakly determined here",
        markup=False,
    )
