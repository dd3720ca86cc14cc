"""An identified apparent mass D goes to ROSS unchanged as its bearing mass m (both f = -(K d + C d'
+ M d'')), and ROSS adds it to the mass of the bearing's node. The simulator's paper rig (a
compressible film) identifies D of about -30 to -50 kg; at the journal node of docs/catalog.md's
ROSS example (about 1 kg of shaft) the rotor's mass matrix is then indefinite and its state matrix
has a root of positive real part (a divergence, > 1000 1/s), which run_modal's modes do not list.
bearing_elements warns of a bearing mass matrix that is not positive (never refuses it: it may be
the film's, on a rotor heavy enough there). Checked with ross-rotordynamics itself."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
from typer.testing import CliRunner

from orbitrig.cli import app

MASSES = ("mxx", "mxy", "myx", "myy")


@pytest.fixture(scope="module")
def exported(synthetic_run, tmp_path_factory):
    out = tmp_path_factory.mktemp("ross_mass")
    res = CliRunner().invoke(app, ["export", str(synthetic_run), "--format", "ross", "--out", str(out)])
    assert res.exit_code == 0, res.output
    return out / "ross_bearings.json"


def _negated(exported, tmp_path):
    """The export with its bearings' apparent masses of the opposite sign, as a compressible film's."""
    doc = json.loads(exported.read_text())
    for bearing in doc["bearings"]:
        for m in MASSES:
            bearing[m] = [-v for v in bearing[m]]
    path = tmp_path / "ross_bearings.json"
    path.write_text(json.dumps(doc))
    return path, doc["bearings"][0]


def _elements(path, nodes):
    from orbitrig.analysis.ross_elements import bearing_elements

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        elements = bearing_elements(path, nodes, point=0)
    return elements, [str(w.message) for w in caught if "apparent mass" in str(w.message)]


def _divergence(elements) -> float:
    """The largest real part (1/s) of the state matrix of docs/catalog.md's example rotor on ``elements``."""
    from orbitrig.analysis.ross_elements import import_ross

    ross = import_ross()
    d = 0.0381
    shaft = [ross.ShaftElement(L=0.2, idl=0.0, odl=d, material=ross.materials.steel) for _ in range(6)]
    disk = ross.DiskElement.from_geometry(n=3, material=ross.materials.steel, width=0.07, i_d=d, o_d=0.3)
    rotor = ross.Rotor(shaft, [disk], elements)
    return float(np.linalg.eigvals(rotor.A(speed=100.0)).real.max())


def test_a_positive_apparent_mass_goes_without_a_word(exported):
    doc = json.loads(exported.read_text())
    assert all(v > 0 for m in ("mxx", "myy") for v in doc["bearings"][0][m])
    elements, said = _elements(exported, [0, 6])
    assert said == []
    assert _divergence(elements) < 1e-2  # 0 within rounding: the free axial and torsional rigid-body motions


def test_a_negative_apparent_mass_is_warned_of_with_its_eigenvalue_and_nodes(exported, tmp_path):
    path, bearing = _negated(exported, tmp_path)
    m = np.array([[bearing["mxx"][0], bearing["mxy"][0]], [bearing["myx"][0], bearing["myy"][0]]])
    low = np.linalg.eigvalsh((m + m.T) / 2)[0]
    assert low < -15  # kg
    elements, said = _elements(path, [0, 6])
    assert len(said) == 1
    assert f"at {bearing['frequency'][0]:.6g} rad/s" in said[0]
    assert f"has the eigenvalue {low:.4g} kg" in said[0] and "node(s) 0, 6" in said[0]
    # what it warns of, in ROSS: the journal nodes are lighter than |low|, the rotor diverges
    assert elements[0].M(100.0)[0, 0] == pytest.approx(bearing["mxx"][0])
    assert _divergence(elements) > 100.0


def test_strict_does_not_refuse_a_negative_apparent_mass(exported, tmp_path):
    path, _ = _negated(exported, tmp_path)
    doc = json.loads(path.read_text())
    for bearing in doc["bearings"]:
        bearing["not_determined"], bearing["fit_warnings"] = [], []
    path.write_text(json.dumps(doc))
    from orbitrig.analysis.ross_elements import bearing_elements

    with pytest.warns(UserWarning, match="apparent mass not positive"):
        assert len(bearing_elements(path, [0], point=0, strict=True)) == 1
