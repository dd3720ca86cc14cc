"""A record's gain matrix must be one the sweep can correct the forces with, and its entries'
standard uncertainties none negative: a typed or edited record with a singular matrix (a row of
zeros, two equal rows) folded the two read forces onto one line and was taken; a negative
``gain_u`` too. Refused when the rig configuration is loaded, naming the record file, the line
and the key."""

from __future__ import annotations

import shutil

import pytest

from orbitrig.config import load_rig
from orbitrig.config.record_setup import UncheckedRecordWarning
from orbitrig.errors import ConfigError
from support.paths import ROOT

NAME = "2026-11-27T101500Z-loads"
RECORD = """date = "2026-11-27T10:15:00Z"
operator = "lab"
step = "loads"
[loads.piezo]
gain = {gain}
gain_u = {gain_u}
"""


def _lab(tmp_path, gain: str, gain_u: str = "[[0.001, 0.0], [0.0, 0.001]]"):
    shutil.copy(ROOT / "config/rig.toml", tmp_path / "rig.toml")
    shutil.copytree(ROOT / "config/calibration", tmp_path / "calibration")
    rig = tmp_path / "rig.toml"
    rig.write_text(rig.read_text().replace("2026-11-26T214732Z-initial", NAME))
    record = tmp_path / "calibration" / f"{NAME}.toml"
    record.write_text(RECORD.format(gain=gain, gain_u=gain_u))
    return rig, record


@pytest.mark.parametrize("gain", ["[[1.0, 1.0], [1.0, 1.0]]", "[[1.02, 0.01], [0.0, 0.0]]"])
def test_a_singular_gain_matrix_is_refused_naming_the_record_line_and_key(tmp_path, gain):
    rig, record = _lab(tmp_path, gain)
    with pytest.raises(ConfigError) as err:
        load_rig(rig)
    assert err.value.file == str(record)
    (problem,) = err.value.problems
    assert problem.startswith("line 5: key 'loads.piezo.gain': a gain matrix must be invertible (condition number ")


def test_a_negative_gain_uncertainty_is_refused(tmp_path):
    rig, record = _lab(tmp_path, "[[1.02, 0.01], [-0.02, 0.98]]", "[[0.001, -0.002], [0.0, 0.001]]")
    with pytest.raises(ConfigError) as err:
        load_rig(rig)
    assert err.value.problems == [
        "line 6: key 'loads.piezo.gain_u[0][1]': Input should be greater than or equal to 0 (got -0.002)"
    ]


def test_a_gain_matrix_with_cross_terms_and_a_reversed_channel_is_taken(tmp_path):
    rig, _ = _lab(tmp_path, "[[1.02, 0.03], [-0.02, -0.98]]")
    with pytest.warns(UncheckedRecordWarning):  # no [channels]: a record written before they were
        assert load_rig(rig).record.force_gain("piezo")[1][1] == -0.98
