"""orbitrig export --format ross, a point whose spin lies outside its tested whirl range and whose
constant fit the run did not store: the constant fit is made from the orbit table, and its U
rests on the calibration uncertainty the run stated (the stored fits' budget parameters), as the
sweep's own constant fit would have. It was statistical only: about a hundredth of the stored
fits' U for K, within one bearing whose other speeds carried the combined U."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from orbitrig.analysis.ross_speed import K_LARGEST, K_REBUILT
from orbitrig.cli import app
from orbitrig.store.fit_record import point_fits
from orbitrig.store.reader import read_run
from test_ross_speed_axis import KEYS, OURS, speed_run

__all__ = ["speed_run"]


def _export_without_the_constant_fit(speed_run, tmp_path, monkeypatch, runout_covariance=None, source_dof=()):
    """The ross export of the run with point 2's constant fit not stored (made here from the orbit
    table), point 2's chosen fit's budget given ``runout_covariance`` and ``source_dof`` (None: the
    key removed, a budget stored before it): (bearing, stored constant fit)."""
    import orbitrig.store.reader as reader

    run = read_run(speed_run)
    point = run.points[2]
    stored = next(f for f in point_fits(point) if (f.lms, f.model, f.freq_dep) == ("piezo", "kcd11", "none"))
    assert stored.result["expanded_uncertainty"]["basis"] == "combined"
    if runout_covariance is not None:
        chosen = point.identification("piezo", "kcd11", "power:1", "ols").result
        chosen["uncertainty"]["runout_covariance"] = runout_covariance
    if source_dof != ():
        budget = point.identification("piezo", "kcd11", "power:1", "ols").result["uncertainty"]
        budget.pop("source_dof")
        if source_dof is not None:
            budget["source_dof"] = [source_dof.get(n) for n in budget["sources"]]
    point.frequencies = [f for f in point.frequencies if abs(f.orbit) < point.settings.spin]  # tested below omega
    point.identifications = [
        i for i in point.identifications if (i.lms, i.model, i.freq_dep) != ("piezo", "kcd11", "none")
    ]  # the constant fit not stored: made here from the same orbit table
    monkeypatch.setattr(reader, "read_run", lambda directory: run)
    res = CliRunner().invoke(
        app, ["export", str(speed_run), "--format", "ross", "--out", str(tmp_path), "--fit", "piezo:kcd11:power:1:ols"]
    )
    assert res.exit_code == 0, res.output
    (bearing,) = json.loads((tmp_path / "ross_bearings.json").read_text())["bearings"]
    return bearing, stored


def test_a_constant_fit_made_here_has_the_runs_calibration_in_U(speed_run, tmp_path, monkeypatch):
    bearing, stored = _export_without_the_constant_fit(speed_run, tmp_path, monkeypatch)
    speed = bearing["speeds"][2]
    assert speed["fit"] == "piezo:kcd11:none:ols (not stored: fitted here from the orbit table)"
    assert speed["basis"] == "combined"
    for key in KEYS:
        name = OURS[key[0]] + key[1:]
        name = "Dxy" if name == "Dyx" else name  # kcd11: Dyx is Dxy
        want = stored.U[stored.names.index(name)]
        assert bearing["U"][key][2] == pytest.approx(want, rel=1e-9), key
        assert bearing[key][2] == pytest.approx(stored.value[stored.names.index(name)], rel=1e-9)
    assert speed["fit_not_determined"] == list(stored.result["not_determined"])
    assert not any("runout" in w for w in speed["fit_warnings"])  # the run stored no runout term


def test_a_constant_fit_made_here_says_it_goes_without_the_stored_runout_term(speed_run, tmp_path, monkeypatch):
    """The chosen power:1 fit's runout covariance (22 x 22) is not the constant fit's (11 x 11) and
    the runout's change of x, y is not stored: U without it (as before), and a fit warning says so."""
    bearing, stored = _export_without_the_constant_fit(speed_run, tmp_path, monkeypatch, (np.eye(22) * 1e6).tolist())
    speed = bearing["speeds"][2]
    name = stored.names.index("Kxx")
    assert bearing["U"]["kxx"][2] == pytest.approx(stored.U[name], rel=1e-9)  # the term left out
    assert (
        "U without the subtracted runout's uncertainty (type B, in the run's U of its stored fits): its "
        "covariance is stored for a fit of 22 coefficients, not for this fit's 11"
    ) in speed["fit_warnings"]


def test_a_constant_fit_made_here_takes_its_k_from_the_budgets_source_dof(speed_run, tmp_path, monkeypatch):
    """The budget keeps each source's dof (source_dof): the fit made here takes each coefficient's
    k as the sweep does (Student's t at its effective dof); the force gains at 3 dof raise the
    entries' k above 2 (2.03 for K_xx here, the gain not dominating), at most to t(3) = 3.31. It took
    the fit's statistical k (2) for all."""
    exact, _ = _export_without_the_constant_fit(speed_run, tmp_path / "a", monkeypatch)
    bearing, stored = _export_without_the_constant_fit(
        speed_run, tmp_path / "b", monkeypatch, source_dof={"fx.gain": 3, "fy.gain": 3}
    )
    speed = bearing["speeds"][2]
    assert speed["k_rule"] == K_REBUILT == exact["speeds"][2]["k_rule"]
    for key in ("kxx", "kyy", "cxx"):
        k = 2.0 * bearing["U"][key][2] / exact["U"][key][2]  # the exact run's k is 2: U scales with k
        assert 2.001 < k <= 3.31, key


def test_a_budget_stored_without_source_dof_keeps_its_largest_k_and_says_so(speed_run, tmp_path, monkeypatch):
    bearing, stored = _export_without_the_constant_fit(speed_run, tmp_path, monkeypatch, source_dof=None)
    speed = bearing["speeds"][2]
    assert speed["k_rule"] == K_LARGEST
    name = stored.names.index("Kxx")
    assert bearing["U"]["kxx"][2] == pytest.approx(stored.U[name], rel=1e-9)  # k 2, as stored
