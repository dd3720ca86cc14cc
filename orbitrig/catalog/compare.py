"""Catalog rows arranged for `orbitrig compare`: the operating variable on the x axis, the
repeated runs at one operating point, and their consistency.

Repeatability of one coefficient: rows of one fit kind whose five conditions (spin,
recess pressure, pressure ratio, static and dynamic eccentricity) and bearing (rig, journal,
clearance, simulator scenario: orbitrig.catalog.bearing) agree form a group when they come
from at least two runs. Each row's standard uncertainty u_i is what differs
from run to run: in a group whose rows share one calibration record
(calibration_record_sha256) the calibration part of U is common to them all and cancels
in their differences, so u_i is the fit's statistical standard error (coefficients_json
"std"); in another group (or where a row stores no standard error) u_i = U_i / k_i, k_i the
row's own coverage factor (coefficients_json "k": 2, or Student's t when the fit's covariance
came from its residual; 2 for a row catalogued before k was stored).
With x_w the 1/u²-weighted mean of the group, chi2 = sum over groups and runs of
((x_i - x_w) / u_i)^2 on sum(n_g - 1) degrees of freedom; p is its upper tail
probability. p well below 0.05: the runs scatter more than their u says.
"""

from __future__ import annotations

import json
import math
from collections import defaultdict
from dataclasses import dataclass
from enum import StrEnum
from typing import Any

import numpy as np

from orbitrig.analysis.typeset import condition_label
from orbitrig.catalog.bearing import KEY_COLUMNS
from orbitrig.catalog.rows import COVERAGE
from reduction.statistics import p_text

Row = dict[str, Any]

#: the columns fixing an operating point
CONDITIONS = ("spin", "recess_pressure", "pressure_ratio", "static_eccentricity", "dynamic_eccentricity")


class Variable(StrEnum):
    """The operating variables `compare` can put on the x axis."""

    STATIC_ECCENTRICITY = "static_eccentricity"
    DYNAMIC_ECCENTRICITY = "dynamic_eccentricity"
    PRESSURE_RATIO = "pressure_ratio"
    SPIN = "spin"

    @property
    def label(self) -> str:
        """The axis label as the paper writes it: the variable's name and symbol (\u03b5 with its
        subscript in mathtext, as the report's operating point: orbitrig.analysis.typeset)."""
        return condition_label(self.value)

    @property
    def predicted_column(self) -> str:
        """The column of a predicted-coefficients CSV that gives this variable (spin in rpm)."""
        return "spin_rpm" if self is Variable.SPIN else self.value

    def of(self, row: Row) -> float:
        """The row's value on the x axis (spin in rpm, the others as stored)."""
        return float(row["spin_rpm"] if self is Variable.SPIN else row[self.value])


class UBasis(StrEnum):
    """The standard uncertainty a repeatability chi2 rests on (module docstring)."""

    STATISTICAL = "u = std. error"  # every group's runs share one calibration record
    EXPANDED = "u = U/k"  # no group does
    MIXED = "u = std. error or U/k"  # some groups do


@dataclass(frozen=True)
class Repeatability:
    coefficient: str
    chi2: float
    dof: int
    p_value: float  # NaN without repeats
    groups: int  # operating points measured in two runs or more
    basis: UBasis = UBasis.EXPANDED
    left_out: int = 0  # repeated rows giving the coefficient without a u (no U, no shared std. error)

    def text(self) -> str:
        without = f"; {self.left_out} without U left out" if self.left_out else ""
        if not self.dof:
            return f"no repeats{without}"
        # two lines of a panel's width: 'p < 1e-300' (an underflow) is longer than a p's digits
        return f"repeats: \u03c7\u00b2 = {self.chi2:.3g} / {self.dof}\n{p_text(self.p_value)}, {self.basis}{without}"


def condition_value(value: Any) -> float:
    """A condition rounded to 9 significant digits: stored and written floats compare equal."""
    return float(f"{float(value):.9g}")


def operating_point(row: Row) -> tuple:
    """The row's conditions, rounded (condition_value)."""
    return tuple(condition_value(row[c]) for c in CONDITIONS)


def other_conditions(row: Row, variable: Variable) -> tuple[tuple[str, float | None], ...]:
    """The row's conditions but ``variable`` (column, value rounded as condition_value; None
    when not stored): the rows of one run that share them are one curve against ``variable``."""
    return tuple(
        (c, None if row.get(c) is None else condition_value(row[c])) for c in CONDITIONS if c != variable.value
    )


def curves(rows: list[Row], variable: Variable) -> dict[tuple, list[Row]]:
    """``rows`` (one run's) by their other conditions, in order of first appearance: a run of
    two pressure ratios plotted against static eccentricity is two curves, not one line
    zigzagging between them."""
    out: dict[tuple, list[Row]] = {}
    for row in rows:
        out.setdefault(other_conditions(row, variable), []).append(row)
    return out


def bearing_key(row: Row) -> tuple:
    """What tells the row's bearing from another's: rig, journal, clearance and scenario (its
    numbers rounded as the conditions are; a row catalogued before these columns were: None and
    "" alike, its rig id alone)."""
    values = (row.get(c) for c in KEY_COLUMNS)
    return (
        row.get("rig_id") or "",
        *("" if v in (None, "") else condition_value(v) if isinstance(v, float) else v for v in values),
    )


def repeat_groups(rows: list[Row]) -> list[list[Row]]:
    """Rows of the same operating point of the same bearing from at least two runs (one fit
    kind assumed)."""
    groups: dict[tuple, list[Row]] = defaultdict(list)
    for row in rows:
        groups[(operating_point(row), bearing_key(row))].append(row)
    return [g for g in groups.values() if len({r["run_id"] for r in g}) >= 2]


def repeatability(rows: list[Row], coefficient: str) -> Repeatability:
    """chi2 of the repeated runs of ``coefficient`` against their U (module docstring)."""
    from reduction.distributions import chi2_sf

    total, dof, n_groups, bases, left_out = 0.0, 0, 0, set(), 0
    for group in repeat_groups(rows):
        pairs, statistical = _values_and_u(group, coefficient)
        left_out += sum(r.get(coefficient) is not None for r in group) - len(pairs)
        if len(pairs) < 2:
            continue
        x, u = np.array(pairs).T
        w = 1.0 / u**2
        total += float(np.sum(((x - np.sum(w * x) / np.sum(w)) / u) ** 2))
        dof, n_groups = dof + len(pairs) - 1, n_groups + 1
        bases.add(UBasis.STATISTICAL if statistical else UBasis.EXPANDED)
    p = float(chi2_sf(total, dof)) if dof else math.nan
    basis = bases.pop() if len(bases) == 1 else (UBasis.MIXED if bases else UBasis.EXPANDED)
    return Repeatability(coefficient, total, dof, p, n_groups, basis, left_out)


def _values_and_u(group: list[Row], coefficient: str) -> tuple[list[tuple[float, float]], bool]:
    """(value, u) of the group's rows giving the coefficient, and whether u is the statistical
    standard error (one calibration record shared by the rows, each storing it) or U / k."""
    given = [r for r in group if r.get(coefficient) is not None]
    records = {r.get("calibration_record_sha256") or "" for r in given}
    std = [_std_error(r, coefficient) for r in given]
    if len(records) == 1 and "" not in records and all(math.isfinite(s) and s > 0 for s in std):
        return [(r[coefficient], s) for r, s in zip(given, std)], True
    u = [(r[coefficient], r[f"{coefficient}_U"] / coverage(r, coefficient)) for r in given if r.get(f"{coefficient}_U")]
    return u, False


def _stored(row: Row) -> dict[str, Any]:
    """The row's coefficients_json as an object ({} when unreadable)."""
    stored = row.get("coefficients_json") or "{}"
    try:
        data = json.loads(stored) if isinstance(stored, str) else stored
    except ValueError:
        return {}
    return data if isinstance(data, dict) else {}


def _std_error(row: Row, coefficient: str) -> float:
    """The fit's statistical standard error of ``coefficient`` (SI), NaN when not stored."""
    try:
        return float((_stored(row).get("std") or {}).get(coefficient, math.nan))
    except (TypeError, ValueError):
        return math.nan


def coverage(row: Row, coefficient: str | None = None) -> float:
    """k of the row's U of ``coefficient`` (coefficients_json "k_values": each coefficient's own),
    else the row's "k" (the largest; a row stored before k_values), COVERAGE (2) when it stores none."""
    stored = _stored(row)
    try:
        k = float((stored.get("k_values") or {}).get(coefficient) or stored.get("k") or COVERAGE)
    except (TypeError, ValueError, AttributeError):
        return COVERAGE
    return k if math.isfinite(k) and k > 0 else COVERAGE


def runs_of(rows: list[Row]) -> dict[str, list[Row]]:
    """Rows by run, in order of first appearance."""
    out: dict[str, list[Row]] = {}
    for row in rows:
        out.setdefault(row["run_id"], []).append(row)
    return out
