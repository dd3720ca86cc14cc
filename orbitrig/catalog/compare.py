"""Catalog rows arranged for `orbitrig compare`: the operating variable on the x axis, the
repeated runs at one operating point, and their consistency.

Repeatability of one coefficient: rows of one fit kind whose five conditions (spin,
recess pressure, pressure ratio, static and dynamic eccentricity) agree form a group
when they come from at least two runs. With u_i = U_i / 2 (the standard uncertainty
behind each run's expanded one, k = 2) and x_w the u-weighted mean of the group,
chi2 = sum over groups and runs of ((x_i - x_w) / u_i)^2 on sum(n_g - 1) degrees of
freedom; p is its upper tail probability. p well below 0.05: the runs scatter more than
their U says.
"""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass
from enum import StrEnum
from typing import Any

import numpy as np

from orbitrig.catalog.rows import COVERAGE

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
        return {
            "static_eccentricity": "static eccentricity \u03b5s",
            "pressure_ratio": "pressure ratio \u03b2",
            "dynamic_eccentricity": "dynamic eccentricity \u03b5d",
            "spin": "spin \u03c9 [rpm]",
        }[self.value]

    @property
    def predicted_column(self) -> str:
        """The column of a predicted-coefficients CSV that gives this variable (spin in rpm)."""
        return "spin_rpm" if self is Variable.SPIN else self.value

    def of(self, row: Row) -> float:
        """The row's value on the x axis (spin in rpm, the others as stored)."""
        return float(row["spin_rpm"] if self is Variable.SPIN else row[self.value])


@dataclass(frozen=True)
class Repeatability:
    coefficient: str
    chi2: float
    dof: int
    p_value: float  # NaN without repeats
    groups: int  # operating points measured in two runs or more

    def text(self) -> str:
        if not self.dof:
            return "no repeats"
        return f"repeats: \u03c7\u00b2 = {self.chi2:.3g} / {self.dof}, p = {self.p_value:.2g}"


def operating_point(row: Row) -> tuple:
    """The row's conditions, rounded to 9 significant digits (stored floats compare equal)."""
    return tuple(float(f"{float(row[c]):.9g}") for c in CONDITIONS)


def repeat_groups(rows: list[Row]) -> list[list[Row]]:
    """Rows of the same operating point from at least two runs (one fit kind assumed)."""
    groups: dict[tuple, list[Row]] = defaultdict(list)
    for row in rows:
        groups[operating_point(row)].append(row)
    return [g for g in groups.values() if len({r["run_id"] for r in g}) >= 2]


def repeatability(rows: list[Row], coefficient: str) -> Repeatability:
    """chi2 of the repeated runs of ``coefficient`` against their U (module docstring)."""
    from scipy.stats import chi2 as chi2_dist

    total, dof, n_groups = 0.0, 0, 0
    for group in repeat_groups(rows):
        pairs = [
            (r[coefficient], r[f"{coefficient}_U"] / COVERAGE)
            for r in group
            if r.get(coefficient) is not None and r.get(f"{coefficient}_U")
        ]
        if len(pairs) < 2:
            continue
        x, u = np.array(pairs).T
        w = 1.0 / u**2
        total += float(np.sum(((x - np.sum(w * x) / np.sum(w)) / u) ** 2))
        dof, n_groups = dof + len(pairs) - 1, n_groups + 1
    p = float(chi2_dist.sf(total, dof)) if dof else math.nan
    return Repeatability(coefficient, total, dof, p, n_groups)


def runs_of(rows: list[Row]) -> dict[str, list[Row]]:
    """Rows by run, in order of first appearance."""
    out: dict[str, list[Row]] = {}
    for row in rows:
        out.setdefault(row["run_id"], []).append(row)
    return out
