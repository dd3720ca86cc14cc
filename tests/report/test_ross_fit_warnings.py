"""orbitrig export --format ross hands each speed's fit warnings to ROSS: the stored fit's
warnings (a chi2 that does not fit the stated u_*, ill-conditioning ...) and a failed adequacy
test of a frequency-dependent fit go into the speed's ``fit_warnings`` and the bearing's, are
printed on standard error, and bearing_elements warns about them (UserWarning) and with
strict=True refuses, checked with ross-rotordynamics itself (the `ross` extra)."""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from orbitrig.cli import app
from orbitrig.store.reader import read_run


def _export(run_dir, out, *args):
    res = CliRunner().invoke(app, ["export", str(run_dir), "--format", "ross", "--out", str(out), *args])
    return res, json.loads((out / "ross_bearings.json").read_text())


def _stored_warnings(run_dir, index, lms, freq_dep):
    fit = read_run(run_dir).points[index].identification(lms, "kcd11", freq_dep)
    return list(fit.result["warnings"]), fit.result.get("adequacy")


def test_each_speed_carries_its_fits_warnings(synthetic_run, tmp_path):
    """The synthetic run's fits all state a chi2 far below its dof (u_* overstated): each speed
    carries it, the bearing lists it with point, speed and fit, and stderr says it."""
    res, doc = _export(synthetic_run, tmp_path)
    assert res.exit_code == 0, res.output  # a warning, as a coefficient not determined
    for bearing, index in zip(doc["bearings"], (0, 1)):
        stored, _ = _stored_warnings(synthetic_run, index, "piezo", "none")
        assert stored and stored[0].startswith("chi2 = ")  # the defect's case: a chi2 warning stored
        (speed,) = bearing["speeds"]
        assert speed["fit_warnings"] == stored
        assert bearing["fit_warnings"] == [
            {"point": index, "spin": speed["spin"], "fit": "piezo:kcd11:none:ols", "warning": w} for w in stored
        ]
        line = f"warning: point {index:04d} at 104.72 rad/s, fit piezo:kcd11:none:ols: {stored[0]}"
        assert line in res.stderr, res.stderr
    assert "fit_warnings" in doc["conventions"]


def test_a_failed_adequacy_test_is_a_fit_warning(synthetic_run, tmp_path):
    """kcd11 power:1 at the synchronous whirl: the likelihood-ratio test does not support its
    frequency dependence; that verdict is handed on with the fit's own warnings."""
    res, doc = _export(synthetic_run, tmp_path, "--fit", "piezo:kcd11:power:1:ols")
    assert res.exit_code == 0, res.output
    stored, adequacy = _stored_warnings(synthetic_run, 0, "piezo", "power:1")
    assert adequacy["supported"] is False
    speed = doc["bearings"][0]["speeds"][0]
    assert speed["used"] == "synchronous"
    expect = f"adequacy ({adequacy['test']}): {adequacy['verdict']}; the frequency dependence exported is not supported"
    assert speed["fit_warnings"] == [*stored, expect]
    assert f"fit piezo:kcd11:power:1:ols: {expect}" in res.stderr


def test_bearing_elements_warns_about_fit_warnings_and_strict_refuses(synthetic_run, tmp_path):
    from orbitrig.analysis.ross_elements import bearing_elements, import_ross

    ross = import_ross()  # the ross extra (tools/run-tests installs .[test,ross])

    _export(synthetic_run, tmp_path)
    path = tmp_path / "ross_bearings.json"
    stored, _ = _stored_warnings(synthetic_run, 0, "piezo", "none")
    with pytest.warns(UserWarning) as caught:
        elements = bearing_elements(path, [0, 6], point=0)
    text = " ".join(str(w.message) for w in caught)
    assert f"fit warnings: point 0000 (104.72 rad/s), fit piezo:kcd11:none:ols: {stored[0]}" in text
    assert all(isinstance(e, ross.BearingElement) for e in elements)
    with pytest.raises(
        ValueError, match=r"fit warnings: point 0000 \(104.72 rad/s\), fit piezo:kcd11:none:ols: chi2 = "
    ):
        bearing_elements(path, [0, 6], point=0, strict=True)


def test_strict_refuses_a_bearing_with_only_fit_warnings(synthetic_run, tmp_path):
    """All coefficients determined (not_determined emptied), the fit's chi2 warning alone: strict
    refuses, the default warns and gives ROSS's elements."""
    from orbitrig.analysis.ross_elements import bearing_elements

    _export(synthetic_run, tmp_path)
    path = tmp_path / "ross_bearings.json"
    doc = json.loads(path.read_text())
    for bearing in doc["bearings"]:
        bearing["not_determined"] = []
    path.write_text(json.dumps(doc))
    with pytest.raises(ValueError, match="fit warnings"):
        bearing_elements(path, [0], point=0, strict=True)
    with pytest.warns(UserWarning, match="fit warnings") as caught:
        assert len(bearing_elements(path, [0], point=0)) == 1
    assert not any("not determined" in str(w.message) for w in caught)
