"""A resumed run corrects its points by the calibration record it stored (run.json
`calibration_record_text`); that text must be the one the run started with, whose SHA-256 its
provenance holds (`calibration_record_sha256`). run.json edited since (a gain, an uncertainty), or
its record text gone (the rig configuration would then read a record of that name from the lab's
folder), would correct the resumed points by another record than the run names: refused before
anything starts, naming run.json and both digests.

Real parts: a run directory as a killed run leaves it (orbitrig.store.writer), `orbitrig sweep
--sim --resume --dry-run` in a subprocess."""

from __future__ import annotations

import json

import pytest

from orbitrig import config as cfg
from orbitrig.run.provenance import Provenance
from orbitrig.store.writer import RunStore

from support.cli_helpers import orbitrig
from support.store_checks import small_matrix

pytestmark = pytest.mark.timeout(120)


def _killed_run(tmp_path):
    rig = cfg.load_rig()
    mat = cfg.matrix_from_text(small_matrix("killed", 8), "killed.toml")
    out = tmp_path / "run"
    prov = Provenance.of_run(rig, "ada").to_dict()
    RunStore.create(
        out, rig_text=rig.text, matrix_text=mat.run_text, matrix_name=mat.name, sim=True, provenance=prov,
        record_text=rig.record_text,
    )  # fmt: skip
    return out, rig


def _resume(out):
    return orbitrig("sweep", "--sim", "--resume", "--dry-run", "--out", str(out), timeout=60, columns=None)


def test_a_resume_refuses_a_stored_record_that_is_not_the_one_the_run_started_with(tmp_path):
    out, rig = _killed_run(tmp_path)
    assert _resume(out).returncode == 0  # as stored: the dry run of the resume
    header = json.loads((out / "run.json").read_text(encoding="utf-8"))
    started = header["provenance"]["calibration_record_sha256"]
    assert started == cfg.digest(rig.record_text)
    edited = rig.record_text.replace("gain_pct = 2.5", "gain_pct = 0.25", 1)
    (out / "run.json").write_text(json.dumps(header | {"calibration_record_text": edited}), encoding="utf-8")
    p = _resume(out)
    assert p.returncode == 2, p.stdout + p.stderr
    text = " ".join(p.stderr.split())
    assert (
        f"{out}/run.json: key 'calibration_record_text': the calibration record stored in this run is not the one it "
        f"started with: its SHA-256 is {cfg.digest(edited)[:12]}..., the run's provenance "
        f"(calibration_record_sha256) says {started[:12]}...; "
    ) in text, text
    assert "Put run.json back as the run wrote it, or start a new run" in text
    # the text gone: the lab's record of that name is not taken in its place
    header.pop("calibration_record_text")
    (out / "run.json").write_text(json.dumps(header), encoding="utf-8")
    p = _resume(out)
    assert p.returncode == 2 and "stored in this run is not the one it started with: it is not there" in p.stderr


def test_a_resume_refuses_a_provenance_without_the_record_digest_and_resumes_a_run_from_before_it(tmp_path):
    """The digest came with the provenance and the record text (run.json's format stayed
    orbitrig-run/2): a provenance without it is an edited run.json, not an older run."""
    out, rig = _killed_run(tmp_path)
    header = json.loads((out / "run.json").read_text(encoding="utf-8"))
    edited = rig.record_text.replace("gain_pct = 2.5", "gain_pct = 0.25", 1)
    prov = {k: v for k, v in header["provenance"].items() if k != "calibration_record_sha256"}
    (out / "run.json").write_text(
        json.dumps(header | {"provenance": prov, "calibration_record_text": edited}), encoding="utf-8"
    )
    p = _resume(out)
    assert p.returncode == 2, p.stdout + p.stderr
    text = " ".join(p.stderr.split())
    assert f"{out}/run.json: key 'provenance.calibration_record_sha256' is missing" in text, text
    # the digest emptied (a run without a record) while a record text is stored: refused as well
    prov["calibration_record_sha256"] = ""
    (out / "run.json").write_text(
        json.dumps(header | {"provenance": prov, "calibration_record_text": edited}), encoding="utf-8"
    )
    p = _resume(out)
    assert p.returncode == 2 and "(calibration_record_sha256) says none" in " ".join(p.stderr.split())
    # a run written before provenance and record text were stored still resumes
    old = {k: v for k, v in header.items() if k not in ("provenance", "calibration_record_text")}
    (out / "run.json").write_text(json.dumps(old), encoding="utf-8")
    p = _resume(out)
    assert p.returncode == 0, p.stdout + p.stderr
