"""run.h5 layout (docs/storage.md), complete points, resume and coefficients.csv."""

import csv
import json

import h5py
import numpy as np
import pytest

from orbitrig import config as cfg
from orbitrig.config import ModelSpec
from orbitrig.run.plan import operating_points
from orbitrig.store.reader import read_run
from orbitrig.store.writer import BlockRecord, PointResults, RunStore, StorageError
from orbitrig.store.status import RunStatus
from reduction.table import OrbitTable


def _record(block, n=3):
    rng = np.random.default_rng(block.freq)
    return BlockRecord(
        block=block,
        measured_orbit_speed=abs(block.orbit),
        raw_counts=rng.integers(-100, 100, (n, 8, 45), dtype=np.int16),
        slots=np.arange(360, dtype=np.int16).reshape(45, 8).T,
        gains=np.ones(8),
        offsets=np.zeros(8),
        mean=np.zeros((8, 45)),
        record_phasors=np.ones((n, 8), complex),
        phasors=np.ones(8, complex),
        dc=np.zeros(8),
        rms_residual=np.zeros(8),
        coherence=np.ones((2, 4)),
        stats={"frames_good": 10, "drop_reasons": {"crc": 1}},
    )


def _results(p):
    t = OrbitTable(
        spin=p.spin,
        orbit=np.array([1.0, 2.0]),
        x=np.ones(2, complex),
        y=-1j * np.ones(2),
        fx=np.ones(2, complex),
        fy=np.ones(2, complex),
        gamma2=np.ones((2, 4)),
    )
    spec = ModelSpec(model="kc8")
    ident = {
        "model": "kc8",
        "freq_dep": "none",
        "method": "ols",
        "n_coefficients": 8,
        "min_frequencies": 2,
        "n_frequencies": 2,
        "coefficients": {"Kxx": 3e7, "Cxx": 8e4},
        "std_errors": {"Kxx": 1e5, "Cxx": None},
        "condition_number": 3.0,
        "residual_rms": 0.1,
        "fit": [],
    }
    idents = {
        ("piezo", spec.key): {"spec": spec, "json": ident},
        ("strain", spec.key): {"spec": spec, "error": "too few frequencies"},
    }
    truth = {"orbit_hz": [1.0], "K0": [[3.1e7, 0], [0, 3e7]], "C0": [[8e4, 0], [0, 8e4]], "D0": [[1, 0], [0, 1]]}
    return PointResults({"piezo": t, "strain": t}, idents, {"fx_amp_ratio": [1.0]}, truth)


def test_store_layout_resume_and_csv(tmp_path):
    rig, m = cfg.load_rig(), cfg.load_matrix(cfg.default_matrix_path("paper"))
    p0, p1 = operating_points(m, rig)[:2]
    s = RunStore.create(tmp_path, rig_text=rig.text, matrix_text=m.text, matrix_name=m.name, sim=True)
    with pytest.raises(StorageError, match="already exists"):
        RunStore.create(tmp_path, rig_text="", matrix_text="", matrix_name="x", sim=True)
    s.begin_point(p0)
    s.logs.add("events", (0.5, "running", "hello"))
    for b in p0.blocks[:2]:
        s.write_block(p0.index, _record(b))
    s.write_results(p0.index, _results(p0))
    s.complete_point(p0.index)
    s.begin_point(p1)  # p1 is left incomplete, as after a kill -9
    s.write_block(p1.index, _record(p1.blocks[0]))

    assert not s.path.exists()  # run.h5 is consolidated when the run ends, or on demand:
    s.finalize()
    with h5py.File(s.path, "r") as f:
        assert f.attrs["format"] == "orbitrig-run/2" and f.attrs["status"] == "running"
        assert "matrix_config" in f.attrs and bool(f.attrs["sim"])
        g = f["points/0000"]
        assert g.attrs["complete"] and g.attrs["spin_rpm"] == pytest.approx(1000)
        fr = g["frequencies/09_fwd"]
        assert fr.attrs["complete"] and fr.attrs["direction"] == 1 and fr.attrs["orbit_hz"] > 0
        assert fr["raw_counts"].dtype == np.int16 and fr["raw_counts"].shape == (3, 8, 45)
        assert fr["coherence"].shape == (2, 4) and fr["phasors"].dtype == np.complex128
        assert json.loads(fr["stats"].attrs["drop_reasons"]) == {"crc": 1}
        assert set(g["table"]) == {"piezo", "strain"} and g["table/piezo/gamma2"].shape == (2, 4)
        assert json.loads(g["identification/piezo__kc8__none__ols"].attrs["json"])["coefficients"]["Kxx"] == 3e7
        assert "error" in g["identification/strain__kc8__none__ols"].attrs
        assert "K0" in json.loads(g["truth"].attrs["json"])
        assert f["logs/events"][0]["message"].decode() == "hello"
        assert not f["points/0001"].attrs["complete"]

    r = RunStore.open_existing(tmp_path)
    assert r.prepare_resume() == [0]
    assert r.set_aside == [
        "point 0001 set aside as aside/0001.incomplete.1 (never completed (no commit record)); "
        "it will be measured again",
        "run.h5 written before this resume removed (stale): consolidated again when the run ends",
    ]
    assert (tmp_path / "aside/0001.incomplete.1/09_fwd.h5").is_file()  # kept, never deleted
    assert "resume: point 0001 set aside" in (tmp_path / "run.log").read_text()
    assert not s.path.exists()  # the stale copy is gone until the run ends again
    rows = list(csv.DictReader(open(r.csv_path)))
    assert [(x["point"], x["lms"], x["model"]) for x in rows] == [("0", "piezo", "kc8"), ("0", "strain", "kc8")]
    assert float(rows[0]["Kxx [N/m]"]) == 3e7 and float(rows[0]["true_Kxx [N/m]"]) == 3.1e7
    assert rows[0]["Cxx_std [N s/m]"] == ""
    assert rows[1]["error"] == "too few frequencies" and rows[1]["Kxx [N/m]"] == ""
    assert list(rows[0])[:15] == [
        "point",
        "label",
        "spin_rpm",
        "recess_pressure_mpa",
        "pressure_ratio",
        "static_eccentricity",
        "dynamic_eccentricity",
        "lms",
        "model",
        "freq_dep",
        "method",
        "n_frequencies",
        "condition_number",
        "residual_rms [N]",
        "error",
    ]
    r.set_status(RunStatus.COMPLETED, "done")  # a final status consolidates run.h5
    with h5py.File(r.path, "r") as f:
        assert f.attrs["status"] == "completed" and list(f["points"]) == ["0000"]


def test_numpy_numbers_in_stats_and_truth_are_stored(tmp_path):
    rig, m = cfg.load_rig(), cfg.load_matrix(cfg.default_matrix_path("demo"))
    p = operating_points(m, rig)[0]
    s = RunStore.create(tmp_path, rig_text=rig.text, matrix_text=m.text, matrix_name=m.name, sim=True)
    s.begin_point(p)
    rec = _record(p.blocks[0])
    rec.stats = {"frames_good": np.int64(7), "drop_reasons": {"crc": np.int64(2)}}
    s.write_block(p.index, rec)
    s.finalize()
    with h5py.File(s.path, "r") as f:
        st = f[f"points/0000/frequencies/{p.blocks[0].tag}/stats"].attrs
        assert st["frames_good"] == 7 and json.loads(st["drop_reasons"]) == {"crc": 2}


def test_the_speeds_written_to_the_drives_are_stored_with_each_block_nan_in_an_older_run(tmp_path):
    """A block's spin_written, orbit_written (rad/s, its REF counts') are read back with it, and
    give the commanded ratio; a run written before they were stored reads NaN: the planned ratio."""
    rig, m = cfg.load_rig(), cfg.load_matrix(cfg.default_matrix_path("paper"))
    p = operating_points(m, rig)[0]
    b = p.blocks[0]
    rpm = 2 * np.pi / 60
    written = (1000.05 * rpm, float(np.sign(b.orbit)) * (round(abs(b.orbit) / rpm / 0.15) * 0.15) * rpm)
    s = RunStore.create(tmp_path, rig_text=rig.text, matrix_text=m.text, matrix_name=m.name, sim=True)
    s.begin_point(p)
    rec = _record(b)
    rec.written = written
    s.write_block(p.index, rec)
    s.write_results(p.index, _results(p))
    s.complete_point(p.index)
    s.finalize()
    assert rec.commanded_turns(p.spin) == pytest.approx(written[0] / abs(written[1]), rel=1e-12)
    assert rec.commanded_turns(p.spin) != pytest.approx(p.spin / abs(b.orbit), rel=1e-6)
    (freq,) = read_run(tmp_path).points[0].frequencies
    assert freq.written == pytest.approx(written, rel=1e-15)
    with h5py.File(s.path, "r") as f:
        assert f["points/0000/frequencies"][freq.name].attrs["spin_written__units"] == "rad/s"
    for path in tmp_path.rglob("*.h5"):  # run.h5 and the block's piece as written before the speeds were stored
        with h5py.File(path, "r+") as f:
            for g in [f, *_groups(f)]:
                for a in ("spin_written", "orbit_written"):
                    if a in g.attrs:
                        del g.attrs[a]
    (old,) = read_run(tmp_path).points[0].frequencies
    assert np.isnan(old.written).all()
    assert _record(b).commanded_turns(p.spin) == pytest.approx(p.spin / abs(b.orbit), rel=1e-15)


def _groups(f: h5py.File) -> list[h5py.Group]:
    found: list[h5py.Group] = []
    f.visititems(lambda _, obj: found.append(obj) if isinstance(obj, h5py.Group) else None)
    return found
