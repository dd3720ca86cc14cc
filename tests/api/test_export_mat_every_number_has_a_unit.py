"""Every number run.mat carries has a unit a program can read (docs/storage.md, Export):
its ``units`` names the unit of every numeric field of one unit (a fit's ``residual_rms`` in
N, its ``n_frequencies``, ``condition_number`` and ``e_n``, the point's ``index``, the run's
``sim`` flag); the per-coefficient and per-channel fields have theirs by ``unit_rules``, and
a struct with a legend of its own (``derived``, ``derived_units``) by that legend. Read with
scipy.io.loadmat and pint, as a lab reads it."""

from __future__ import annotations

import numpy as np
import pint
import pytest
from scipy.io import loadmat

from orbitrig.store.export import export_run

UREG = pint.UnitRegistry()
#: run.mat's fields whose unit differs per entry: unit_rules says where it is written
PER_ENTRY = {
    "coefficients",
    "std_errors",
    "U",
    "interval_95",
    "interval_95_statistical",
    "statistical",
    "systematic",
    "combined",
    "expanded",
    "truth",
    "covariance",
    "mean",
    "dc",
    "phasors",
    "uncertainty",
}


@pytest.fixture(scope="module")
def exported(sim_run, tmp_path_factory):
    out = tmp_path_factory.mktemp("export_units")
    export_run(sim_run, "mat", out)
    return out


def _numeric_fields(struct: dict, path: str) -> list[tuple[str, str]]:
    """(path, field) of every numeric leaf of a loadmat(simplify_cells=True) struct, the
    structs that state units (``units``, ``*_units``) left out; the leaves of a struct beside
    its own legend (``derived`` and ``derived_units``) only where that legend lacks them."""
    found = []
    for name, value in struct.items():
        if name == "units" or name.endswith(("_units", "_utf8")):
            continue
        if isinstance(value, dict) and f"{name}_units" in struct:  # a struct with its own legend
            found += [(w, n) for w, n in _numeric_fields(value, f"{path}.{name}") if n not in struct[f"{name}_units"]]
        elif isinstance(value, dict):
            found += _numeric_fields(value, f"{path}.{name}")
        elif not isinstance(value, str) and np.asarray(value).dtype.kind in "biufc":
            found.append((f"{path}.{name}", name))
    return found


def test_run_mat_states_the_unit_of_every_numeric_field(exported):
    m = loadmat(exported / "run.mat", simplify_cells=True)
    units = m["units"]
    fields = _numeric_fields(m["points"], "points") + _numeric_fields(m["run"], "run")
    fit = m["points"]["p0000"]["identification"]["piezo__kcd11__none__ols"]
    assert {"residual_rms", "n_frequencies", "condition_number", "e_n"} <= set(fit)
    missing = sorted({where for where, name in fields if name not in units and name not in PER_ENTRY})
    assert not missing, f"numeric fields without a unit in run.mat's units: {missing}"
    assert units["residual_rms"] == "N"  # a force, as coefficients.csv's residual_rms [N]
    rms = UREG.Quantity(fit["residual_rms"], units["residual_rms"])
    assert fit["residual_rms"] > 0.0 and rms.to("mN").magnitude == pytest.approx(1e3 * fit["residual_rms"])
    for name in ("n_frequencies", "condition_number", "e_n", "index", "sim"):
        assert units[name] == "1", name
    for unit in units.values():
        UREG.parse_units(unit)
