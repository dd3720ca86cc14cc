"""ross_bearings.json is strict JSON (RFC 8259: jq, JSON.parse, GNU Octave's jsondecode): a U
that could not be estimated (a frequency-dependent fit stored without its covariance) is null,
never NaN; the coefficient is listed as not determined and the messages say its U is unknown
rather than printing 'U = nan ... (U > |value|)'."""

from __future__ import annotations

import json

import pytest

from orbitrig.analysis.ross_elements import bearing_elements
from orbitrig.analysis.ross_export import export_ross
from orbitrig.analysis.ross_speed import FitSpec
from orbitrig.load_systems import LoadSystem
from orbitrig.store.reader import read_run
from support.octave import octave_eval


def _refuse(constant: str):
    raise ValueError(f"not JSON: {constant}")


@pytest.fixture
def exported(synthetic_run, tmp_path):
    run = read_run(synthetic_run)
    fit = run.points[0].identification(LoadSystem.PIEZO, "kcd11", "power:1")
    fit.result["covariance"] = None  # no covariance stored: U of a sum over orders unknown
    done = export_ross(run, tmp_path, FitSpec(LoadSystem.PIEZO, "kcd11", "power:1"), None)
    return done


def test_an_unknown_u_is_null_and_named_unknown(exported):
    doc = json.loads(exported.path.read_text(), parse_constant=_refuse)
    bearing = next(b for b in doc["bearings"] if b["points"] == [0])
    assert bearing["U"]["kxx"] == [None] and isinstance(bearing["kxx"][0], float)
    assert {"kxx", "cyy"} <= {n["coefficient"] for n in bearing["not_determined"]}
    assert all(n["U"] is None for n in bearing["not_determined"])
    said = [n for n in exported.selection.notes if "point 0000" in n and ": kxx = " in n]
    assert len(said) == 1 and "with U unknown (not estimated) is not determined" in said[0], said
    assert not any("nan" in n for n in exported.selection.notes)
    with pytest.warns(UserWarning, match=r"kxx = [-0-9.e+]+ N/m with U unknown \(not estimated\)"):
        bearing_elements(exported.path, [0], point=0)


def test_octave_jsondecode_reads_the_unknown_u_as_nan(exported):
    done = octave_eval(
        "d = jsondecode(fileread('ross_bearings.json')); b = d.bearings;"
        " if iscell(b) b = b{1}; else b = b(1); end;"
        " printf('%d %d %d\\n', numel(b.U.kxx), isnan(b.U.kxx(1)), isfinite(b.kxx(1)));",
        exported.path.parent,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["1", "1", "1"], done.stdout
