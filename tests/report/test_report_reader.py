"""Reading a run directory (docs/storage.md) into plain data."""

from __future__ import annotations

import shutil

import h5py
import numpy as np
import pytest
from support.report_synthetic import K_TRUE

from orbitrig.analysis.typeset import operating_point_html, operating_point_math
from orbitrig.store.reader import RunDirError, freq_dep_from_key, freq_dep_key, read_run
from reduction.table import OrbitTable


def test_reads_points_settings_tables_and_results(synthetic_run):
    run = read_run(synthetic_run)
    assert run.status == "stopped" and run.status_message == "synthetic run"
    assert run.sim and run.matrix_name == "synthetic" and "[[models]]" in run.matrix_config
    assert [p.name for p in run.points] == ["0000", "0001", "0002"]
    assert [p.complete for p in run.points] == [True, True, False]
    assert [p.index for p in run.complete_points] == [0, 1]
    p = run.points[1]
    assert p.settings.spin == pytest.approx(1000 * np.pi / 30)
    assert p.settings.spin_rpm == 1000 and p.settings.recess_pressure == pytest.approx(0.4826e6)
    assert p.settings.static_eccentricity == pytest.approx(0.15)
    assert operating_point_math(p.settings) == (  # the figures' titles: SI as stored, typeset at the edges' units
        "\u03c9 = 1000 rpm, \u03b5$_\\mathrm{d}$ = 0.04, \u03b5$_\\mathrm{s}$ = 0.15, p$_\\mathrm{r}$ = 0.4826 MPa, \u03b2 = 0.25"
    )
    assert operating_point_html(p.settings) == (  # the page's heading of the point
        "\u03c9 = 1000 rpm, \u03b5<sub>d</sub> = 0.04, \u03b5<sub>s</sub> = 0.15, p<sub>r</sub> = 0.4826 MPa, \u03b2 = 0.25"
    )
    assert set(p.tables) == {"piezo", "strain"}
    t = p.tables["piezo"]
    assert isinstance(t, OrbitTable) and t.n == 20 and t.gamma2.shape == (20, 4)
    assert len(p.frequencies) == 20
    assert {f.direction for f in p.frequencies} == {1, -1}
    assert all(f.coherence.shape == (2, 4) for f in p.frequencies)
    assert np.allclose(p.truth["K0"], K_TRUE)
    assert p.lms_comparison["fx_amp_ratio"] == pytest.approx([1.018] * 20, rel=1e-5)


def test_stored_identifications_keep_spec_and_refusals(synthetic_run):
    point = read_run(synthetic_run).points[0]
    power = point.identification("piezo", "kcd11", "power:1")
    assert power is not None and power.ok and power.method == "ols"
    assert power.result["n_coefficients"] == 22 and "Kxx_1" in power.result["coefficients"]
    # kcd12 with poly:8 needs 11 powers of Omega per real part: 10 frequencies cannot: stored as a refusal
    refused = point.identification("strain", "kcd12", "poly:8")
    assert refused is not None and not refused.ok and refused.error


def test_freq_dep_key_round_trip():
    for spec in ("none", "power:2", "power:auto", "power:1,2,3", "poly:2"):
        assert freq_dep_from_key(freq_dep_key(spec)) == spec


def test_missing_directory(tmp_path):
    with pytest.raises(RunDirError, match="no such directory") as err:
        read_run(tmp_path / "nope")
    assert err.value.file == str(tmp_path / "nope")


def test_directory_without_run_file(tmp_path):
    with pytest.raises(RunDirError, match="no run.h5"):
        read_run(tmp_path)


def test_run_file_that_is_not_hdf5(tmp_path):
    (tmp_path / "run.h5").write_bytes(b"this is not HDF5\n" * 10)
    with pytest.raises(RunDirError) as err:
        read_run(tmp_path)
    assert err.value.file == str(tmp_path / "run.h5") and "HDF5" in str(err.value)


def test_wrong_format_attribute(tmp_path, synthetic_run):
    shutil.copy(synthetic_run / "run.h5", tmp_path / "run.h5")
    with h5py.File(tmp_path / "run.h5", "r+") as f:
        f.attrs["format"] = "something-else/9"
    with pytest.raises(RunDirError, match="something-else/9"):
        read_run(tmp_path)


def test_a_results_group_named_after_no_load_measuring_system(tmp_path, synthetic_run):
    shutil.copy(synthetic_run / "run.h5", tmp_path / "run.h5")
    with h5py.File(tmp_path / "run.h5", "r+") as f:
        fits = f["points/0000/identification"]
        key = next(k for k in fits if k.startswith("piezo__"))
        fits.move(key, "Piezo" + key[len("piezo") :])
    with pytest.raises(RunDirError, match=r"'Piezo' is not a load measuring system \(piezo, strain\)") as err:
        read_run(tmp_path)
    assert err.value.file == str(tmp_path / "run.h5") and "/points/0000/identification/Piezo__" in str(err.value)
