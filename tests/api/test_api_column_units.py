"""docs/api.md: every DataFrame's ``attrs["units"]`` gives each column of one unit a unit pint
parses, "1" for a dimensionless number or a flag and "" only for text. A column of numbers with ""
reads as text to a program that sorts columns by that rule (the coefficients' ``point``); a
column named as an attribute of run.h5's point group has that attribute's unit."""

from __future__ import annotations

import h5py
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
            assert col in units, f"{name}.{col}: no unit"
            if kind in "biufc":  # a flag (points' `complete`) is a dimensionless number too
                assert units[col] != "", f"{name}.{col}: numbers ({df[col].dtype}) with the unit of text"
                UREG.parse_units(units[col])
            else:
                assert units[col] == "", f"{name}.{col}: text with unit {units[col]!r}"


def test_coefficients_point_is_a_dimensionless_number(run):
    coef = run.coefficients
    assert coef.attrs["units"]["point"] == "1" and coef["point"].dtype.kind == "i"
    assert all(coef.attrs["units"][k] == "" for k in ("lms", "model", "freq_dep", "method", "error"))


def test_points_give_each_column_the_unit_run_h5_gives_it(run, sim_run):
    """`complete` is a flag: "1" (dimensionless) as run.h5's complete__units and the catalog have it."""
    units = run.points.attrs["units"]
    assert units["complete"] == "1" and UREG.parse_units(units["complete"]).dimensionless
    assert run.points["complete"].dtype.kind == "b" and run.points["complete"].all()
    with h5py.File(sim_run / "run.h5", "r") as f:
        attrs = f["points/0000"].attrs
        stated = {k.removesuffix("__units"): str(attrs[k]) for k in attrs if k.endswith("__units")}
    shared = sorted(set(stated) & set(units))
    assert "complete" in shared and len(shared) >= 8
    assert {k: units[k] for k in shared} == {k: stated[k] for k in shared}
