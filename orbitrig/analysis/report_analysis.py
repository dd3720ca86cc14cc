"""What `orbitrig report` shows of one operating point: the sweep's identifications repeated
from the stored orbit tables (a repetition that differs from the stored result is named), each
frequency-dependent fit tested against the constant one, and the derived quantities of every fit (at the
planned orbit frequencies, as the exports);
and which constant model the cross-point figures compare."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from orbitrig.analysis.quality import (
    Band,
    LmsComparison,
    Verdict,
    adequacy_verdicts,
    band_of,
    derived_of,
    lms_comparison,
    warnings_of,
)
from orbitrig.analysis.reduce import Reduced, reidentify
from orbitrig.errors import ReductionError
from orbitrig.load_systems import DIFFERENCE, LMS, LoadSystem
from orbitrig.store.stored_run import Point
from reduction.derived import Derived
from reduction.identify import Method
from reduction.models import is_constant, parse_freq_dep

#: compared across the two load measuring systems, first one present wins
PREFERRED_MODELS = (("kcd11", "none"), ("kc8", "none"), ("kc7", "none"), ("kcd12", "none"))


@dataclass
class PointReport:
    """What the report shows of one operating point."""

    point: Point
    results: dict[LoadSystem, list[Reduced]] = field(default_factory=dict)  # lms -> re-identified
    plots: list[Path] = field(default_factory=list)
    reused: bool = False  # the plots are an earlier report's, unchanged (orbitrig.analysis.report_cache)
    mismatches: list[str] = field(default_factory=list)  # stored vs repeated identification
    unreadable: list[str] = field(default_factory=list)  # stored blocks the signal figures could not read
    verdicts: dict[LoadSystem, list[Verdict]] = field(default_factory=dict)  # lms -> model adequacy
    derived: dict[LoadSystem, list[tuple[Reduced, Derived]]] = field(default_factory=dict)  # lms -> derived
    #: fit_key(result) -> the covariance its figures draw (not by id(): a point analysed in a
    #: worker process comes back pickled, its results new objects)
    bands: dict[tuple[str, ...], Band] = field(default_factory=dict)

    def band(self, r: Reduced) -> Band | None:
        """The covariance the figures of result ``r`` draw (None: not analysed here)."""
        return self.bands.get(fit_key(r))

    def fit_warnings(self) -> list[str]:
        """'<lms> <model> <freq-dep> warns: <text>' for every warning of a repeated or stored fit,
        and '<lms> <model> <freq-dep> refused: <reason>' for every stored refusal."""
        out = [
            f"{r.lms} {r.model} {r.freq_dep} warns: {w}"
            for rs in self.results.values()
            for r in rs
            for w in warnings_of(r)
        ]
        out += [
            f"{i.lms} {i.model} {i.freq_dep} refused: {(i.error or '').splitlines()[0]}"
            for i in self.point.identifications
            if not i.ok
        ]
        return out + self.unreadable


def fit_key(r: Reduced) -> tuple[str, ...]:
    """What tells one result of a point from the others: load system, model, freq-dep, method."""
    return (str(r.lms), r.model, r.freq_dep, str(r.method))


def fit_label(r: Reduced, name_ols: bool = False) -> str:
    """'kcd11 (11 coef.)', 'kcd11 power:1 (22 coef.)' - the paper's wording; a method other
    than ols once after it ('kc8 (8 coef.), wls'), ols too with ``name_ols`` (the tables'
    headings: 'kc8 (8 coef.), ols')."""
    ident = r.identification
    fd = "" if is_constant(r.freq_dep) else f" {r.freq_dep}"
    if ident is not None and ident.exponent and parse_freq_dep(r.freq_dep).auto:
        fd = f" power:{ident.exponent} (auto)"
    n = f" ({ident.n_coefficients} coef.)" if ident is not None else ""
    method = "" if r.method == Method.OLS and not name_ols else f", {r.method}"
    return f"{r.model}{fd}{n}{method}"


def _compare(r: Reduced, stored: dict) -> list[str]:
    """Name coefficients where the repeated identification differs from the stored one."""
    if r.identification is None:
        return [f"{r.lms} {r.model} {r.freq_dep}: stored result, but repeating it was refused: {r.error}"]
    out = []
    coefs = stored.get("coefficients", {})
    new = r.identification.coefficients
    scale = {m: max((abs(v) for k, v in coefs.items() if k[0] == m), default=0.0) for m in "KCD"}
    for k, v in coefs.items():
        w = new.get(k)
        if w is None or not math.isclose(v, w, rel_tol=1e-6, abs_tol=1e-9 * scale.get(k[0], 0.0)):
            out.append(f"{r.lms} {r.model} {r.freq_dep}: {k} stored {v:.6g}, repeated {w}")
    return out


def analyse_point(point: Point) -> PointReport:
    """Repeat the sweep's identifications of one point (both LMS); test each frequency-dependent
    fit against the constant one and form the derived quantities of every fit."""
    pr = PointReport(point)
    for stored in point.identifications:
        if stored.lms not in point.tables or stored.result is None:  # refused: nothing to repeat
            continue
        try:
            r = reidentify(point, stored)
        except ReductionError as err:  # a stored spec this version of reduction rejects
            pr.mismatches.append(f"{stored.lms} {stored.model} {stored.freq_dep}: cannot be repeated: {err}")
            continue
        pr.mismatches += _compare(r, stored.result)
        if r.identification is not None:
            pr.results.setdefault(stored.lms, []).append(r)
    for lms, table in point.tables.items():
        results = pr.results.get(lms, [])
        pr.verdicts[lms] = adequacy_verdicts(lms, results)
        pr.bands.update({fit_key(r): band_of(r) for r in results})
        planned = planned_orbits(point, table.orbit)
        pr.derived[lms] = [(r, d) for r in results if (d := derived_of(r, planned, pr.bands[fit_key(r)])) is not None]
    return pr


def planned_orbits(point: Point, measured: np.ndarray) -> np.ndarray:
    """|Omega| (rad/s) of the point's complete blocks as planned, where the sweep formed the
    derived quantities the exports give (orbitrig.run.identification); the orbit table's
    `measured` speeds (rad/s) of a point stored without its blocks."""
    planned = np.unique([abs(f.orbit) for f in point.frequencies if f.complete])
    return planned if planned.size else np.abs(np.asarray(measured, dtype=float))


def preferred(pr: PointReport, model: tuple[str, str] | None = None) -> dict[LoadSystem, Reduced]:
    """The first constant-coefficient model of PREFERRED_MODELS (or `model`) that was
    identified from both load measuring systems, per LMS; {} when there is none."""
    for spec in [model] if model else PREFERRED_MODELS:
        found = {lms: r for lms in LMS for r in pr.results.get(lms, []) if (r.model, r.freq_dep) == spec}
        if len(found) == len(LMS):
            return found
    return {}


def consistency(pr: PointReport) -> tuple[Reduced, Reduced, LmsComparison] | None:
    """The two systems' fits of the preferred model in DIFFERENCE's order (a, b) and their
    comparison, as the page and report.pdf show it; None without both or without a comparison."""
    found = preferred(pr)
    if len(found) != len(LMS):
        return None
    a, b = (found[lms] for lms in DIFFERENCE)
    comparison = lms_comparison(a, b)
    return None if comparison is None else (a, b, comparison)
