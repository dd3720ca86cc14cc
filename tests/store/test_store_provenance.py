"""The provenance a run reads back (every export carries it): the same text whether the run
is read from its pieces (a run in progress or killed: run.json) or from run.h5, the sensors'
serial numbers as one JSON object of channel -> serial."""

from __future__ import annotations

import json

import h5py

from orbitrig.store.reader import read_run
from orbitrig.store.stored_run import PROVENANCE_KEYS
from support.report_synthetic import write_synthetic_run

SERIALS = {"fx_piezo": "PZ-2231-X", "y_b": "EC-5583-YB"}
PROVENANCE = {
    "operator": "alice",
    "rig_id": "rigA",
    "host": "bench",
    "calibration_record": "2026-01-01.toml",
    "calibration_record_sha256": "ab" * 32,
    "sensor_serials": SERIALS,
    "started": "2026-11-26T10:00:00+00:00",
}


def test_a_killed_run_and_a_finished_one_read_the_same_provenance(tmp_path):
    killed = write_synthetic_run(tmp_path / "killed", finished=False, provenance=PROVENANCE)
    done = write_synthetic_run(tmp_path / "done", provenance=PROVENANCE)
    assert not (killed / "run.h5").exists() and (done / "run.h5").exists()
    from_pieces, from_h5 = read_run(killed).provenance, read_run(done).provenance
    assert list(from_pieces) == list(from_h5) == list(PROVENANCE_KEYS)
    for prov in (from_pieces, from_h5):
        assert json.loads(prov["sensor_serials"]) == SERIALS
        assert prov["operator"] == "alice" and prov["calibration_record_sha256"] == "ab" * 32
    assert from_pieces["ended"] == "" and from_h5["ended"]  # a killed run has not ended
    with h5py.File(done / "run.h5", "r") as f:
        assert json.loads(f.attrs["sensor_serials"]) == SERIALS
