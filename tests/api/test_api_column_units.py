"""docs/api.md: every DataFrame's ``attrs["units"]`` gives each column of one unit a unit pint
parses, "1" for a dimensionless number and "" only for text. A column of numbers with ""
reads as text to a program that sorts columns by that rule (the coefficients' ``point``)."""

from __future__ import annotations

import pytest

import orbitrig
from support.units import UREG


@pytest.fixture(scope="module")
def run(sim_run):
    return orbitrig.open_run(sim_run)


def _frames(run):
    fit = run.fit(0, "piezo", "kcd11")
    return {
        "points": run.points,
        "table": run.table(0, "piezo"),
        "coefficients": run.coefficients,
        "derived": fit.derived,
    }


def test_numbers_have_a_unit_and_only_text_has_none(run):
    for name, df in _frames(run).items():
        units = df.attrs["units"]
        for col in df.columns:
            kind = df[col].dtype.kind
            if kind == "b":
                continue  # a flag (points' `complete`)
            assert col in units, f"{name}.{col}: no unit"
            if kind in "iufc":
                assert units[col] != "", f"{name}.{col}: numbers ({df[col].dtype}) with the unit of text"
                UREG.parse_units(units[col])
            else:
                assert units[col] == "", f"{name}.{col}: text with unit {units[col]!r}"


def test_coefficients_point_is_a_dimensionless_number(run):
    coef = run.coefficients
    assert coef.attrs["units"]["point"] == "1" and coef["point"].dtype.kind == "i"
    assert all(coef.attrs["units"][k] == "" for k in ("lms", "model", "freq_dep", "method", "error"))
