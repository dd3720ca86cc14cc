"""bearing_elements given a file in the export's layout made by hand (docs/catalog.md) names the
file, the bearing entry and the field it lacks or cannot use: it raised a bare KeyError 'myy' or
'not_determined', or let ROSS fail on arrays of different lengths; a hand-made file needs no
not_determined. ROSS is the `ross` extra, which tools/run-tests installs: without it these fail, not skip."""

from __future__ import annotations

import json

import pytest

from orbitrig.analysis.ross_speed import KEYS
from orbitrig.errors import ExportFileError


def _bearing(**changes):
    bearing = {"lms": "piezo", "points": [0, 1], "frequency": [100.0, 200.0]}
    bearing |= {k: [1.0e7, 1.1e7] if k[0] == "k" else [1.0e3, 1.1e3] if k[0] == "c" else [0.0, 0.0] for k in KEYS}
    return bearing | changes


def _write(tmp_path, bearing):
    path = tmp_path / "hand.json"
    path.write_text(json.dumps({"bearings": [bearing]}))
    return path


def test_a_hand_made_file_without_not_determined_is_read(tmp_path):
    from orbitrig.analysis.ross_elements import bearing_elements

    elements = bearing_elements(_write(tmp_path, _bearing()), [0, 6], strict=True)
    assert [e.n for e in elements] == [0, 6]
    assert elements[0].kxx_interpolated(150.0) == pytest.approx(1.05e7)


@pytest.mark.parametrize(
    "bearing, why",
    [
        ({k: v for k, v in _bearing().items() if k != "myy"}, r"bearings\[0\]: no field 'myy'"),
        (_bearing(kxy=[1.0]), r"bearings\[0\]\.kxy: not a list of 2 numbers \(one per speed\)"),
        (_bearing(cxx=[1.0, "a"]), r"bearings\[0\]\.cxx: not a list of 2 numbers"),
        (_bearing(frequency=[200.0, 100.0]), r"bearings\[0\]\.frequency: not ascending"),
        (_bearing(points=0), r"bearings\[0\]\.points: not a list"),
        ("piezo", r"bearings\[0\]: not an object"),
    ],
)
def test_a_bearing_it_cannot_use_is_named_with_the_field(tmp_path, bearing, why):
    from orbitrig.analysis.ross_elements import bearing_elements

    path = _write(tmp_path, bearing)
    with pytest.raises(ExportFileError, match=rf"^{path}: {why}"):
        bearing_elements(path, [0, 6])
