"""The provenance a run reads back (every export carries it): the same text whether the run
is read from its pieces (a run in progress or killed: run.json) or from run.h5, the sensors'
serial numbers as one JSON object of channel -> serial."""

from __future__ import annotations

import json

import h5py

from orbitrig.config import digest, load_rig, rig_from_text
from orbitrig.run.provenance import Provenance
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
    "calibration_record_seal": "as written",
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
        assert prov["calibration_record_seal"] == "as written"
    assert from_pieces["ended"] == "" and from_h5["ended"]  # a killed run has not ended
    with h5py.File(done / "run.h5", "r") as f:
        assert json.loads(f.attrs["sensor_serials"]) == SERIALS
        assert f.attrs["calibration_record_seal"] == "as written"


def test_the_provenance_says_whether_the_record_was_as_written():
    """run.log's line and run.json's provenance: a record whose SHA-256 line matches its text is
    "as written"; one without the line (typed in, or written before records held one) "not
    verifiable"; no record, neither."""
    rig = load_rig()  # its active record, an initial one, is sealed
    assert rig.record_text and "\nsha256 = " in rig.record_text
    sealed = Provenance.of_run(rig, "alice")
    sha = digest(rig.record_text)
    assert f"calibration record {rig.calibration_record} (sha256 {sha[:12]}, as written)" in sealed.summary()
    assert sealed.to_dict()["calibration_record_seal"] == "as written"
    typed = "\n".join(ln for ln in rig.record_text.splitlines() if not ln.startswith("sha256 = ")) + "\n"
    unsealed = Provenance.of_run(rig_from_text(rig.text, "rig.toml", record_text=typed), "alice")  # as a run's copy
    assert f"(sha256 {digest(typed)[:12]}, not verifiable)" in unsealed.summary()
    assert unsealed.to_dict()["calibration_record_seal"] == "not verifiable"
    bare = "\n".join(ln for ln in rig.text.splitlines() if not ln.startswith("calibration_record"))
    none = Provenance.of_run(rig_from_text(bare, "rig.toml"), "alice")
    assert none.summary().endswith("calibration record none") and none.to_dict()["calibration_record_seal"] == ""
