"""The API's docstrings (`help(run.points)`, what a notebook shows) name the units of what
each member returns: every unit its DataFrame's or Dataset's attributes give (and so pint
reads) appears in the member's docstring, on a simulated run."""

from __future__ import annotations

import inspect

import pytest

import orbitrig
from orbitrig.store.run_data import Fit, RunData


def _units(*mappings) -> set[str]:
    """The units named (dimensionless "1" and text "" left out); an Omega^r term's by its family."""
    found = {u.split(" (rad/s)")[0] for m in mappings for u in m.values()}
    return found - {"", "1"}


@pytest.fixture(scope="module")
def run(sim_run):
    return orbitrig.open_run(sim_run)


def test_the_run_members_name_their_units(run):
    for name, frame in (("points", run.points), ("table", run.table(0)), ("coefficients", run.coefficients)):
        doc = inspect.getdoc(getattr(RunData, name))
        assert 'attrs["units"]' in doc, name
        assert all(u in doc for u in _units(frame.attrs["units"])), (name, _units(frame.attrs["units"]), doc)


def test_the_fit_members_name_their_units(run):
    fit = run.fit(0, "piezo", "kcd11")
    coefficients, derived = fit.coefficients, fit.derived
    doc = inspect.getdoc(Fit.coefficients)
    assert _units(coefficients.attrs["row_units"]) == {"N/m", "N s/m", "kg"}
    assert all(u in doc for u in _units(coefficients.attrs["row_units"])) and "(rad/s)^-r" in doc, doc
    doc = inspect.getdoc(Fit.derived)
    assert all(u in doc for u in _units(derived.attrs["units"])), (_units(derived.attrs["units"]), doc)
    assert "entry_units" in inspect.getdoc(Fit.covariance)
    assert fit.lms_consistency is not None and inspect.getdoc(Fit.lms_consistency)


def test_the_waveforms_name_their_units(run):
    wave = run.waveforms(0)
    doc = inspect.getdoc(RunData.waveforms)
    named = {wave[v].attrs["units"] for v in ("theta", "orbit_hz")} | set(wave["unit"].values.tolist())
    assert named == {"rad", "Hz", "N", "m"}
    assert all(u in doc for u in named) and "units_<channel>" in doc, doc
