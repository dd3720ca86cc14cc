"""A run's provenance names the code that made it (orbitrig.run.provenance.software_version): the
version number plus a digest of the distribution's Python sources, and `git describe` when the
package runs from a git checkout. Two trees that differ by one line of a source file stamp different
versions (so a resume with other code warns, orbitrig.run.run_dir.resume_events); the same tree the
same one, also outside a checkout (an installed wheel: no git part)."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

from orbitrig import __version__
from orbitrig.run import provenance
from orbitrig.run.provenance import PACKAGES, Provenance, source_digest, software_version
from support.paths import ROOT

PRINT = "from orbitrig.run.provenance import software_version; print(software_version())"


def _version_in(tree: Path) -> str:
    out = subprocess.run(
        [sys.executable, "-I", "-c", f"import sys; sys.path.insert(0, {str(tree)!r}); {PRINT}"],
        cwd=tree,
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    )
    return out.stdout.strip()


def _copy(dst: Path) -> Path:
    for name in PACKAGES:
        shutil.copytree(ROOT / name, dst / name, ignore=shutil.ignore_patterns("__pycache__"))
    return dst


def test_the_version_names_the_source_and_the_checkout(monkeypatch):
    v = software_version()
    assert re.fullmatch(rf"orbitrig {re.escape(__version__)} \(source [0-9a-f]{{12}}(, git [0-9a-z.-]+)?\)", v), v
    assert f"source {source_digest()}" in v
    if (ROOT / ".git").exists() and shutil.which("git"):
        assert ", git " in v, v

    def again(*_a, **_k):
        raise AssertionError("computed again")

    # computed once per process: asked again, it neither hashes the sources nor asks git
    monkeypatch.setattr(provenance.hashlib, "sha256", again)
    monkeypatch.setattr(provenance.subprocess, "run", again)
    assert software_version() == v


def test_other_sources_stamp_another_version_the_same_sources_the_same(tmp_path):
    a, b = _copy(tmp_path / "a"), _copy(tmp_path / "b")
    va = _version_in(a)
    assert _version_in(b) == va  # the same sources, another place, no checkout: the same version
    assert ", git" not in va and va.startswith(f"orbitrig {__version__} (source ")
    with (b / "reduction" / "fourier.py").open("a") as f:
        f.write("# one more line\n")
    vb = _version_in(b)
    assert vb != va and vb.split(" (")[0] == va.split(" (")[0]  # the version number alone would not tell


def test_the_provenance_of_a_run_carries_it():
    from orbitrig.config import load_rig

    assert Provenance.of_run(load_rig(), "ada").software_version == software_version()


def test_the_run_files_name_the_code(tmp_path):
    """run.h5, the reader (pieces or run.h5) and so every export, the report and the catalog give
    orbitrig's version as the provenance names it (source digest, git), then the libraries'."""
    import h5py

    from orbitrig.config import load_rig
    from orbitrig.store.reader import read_run
    from support.report_synthetic import write_synthetic_run

    prov = Provenance.of_run(load_rig(), "ada").to_dict()
    run_dir = write_synthetic_run(tmp_path / "run", n_points=1, incomplete=0, provenance=prov)
    with h5py.File(run_dir / "run.h5", "r") as f:
        stored = str(f.attrs["software_version"])
        where = str(f.attrs["calibration_record__description"])
    # a lab's record is in its own calibration/ folder, not in the shipped config/ a reader would search
    assert "beside rig.toml" in where and "config/" not in where, where
    assert stored.startswith(software_version() + ", numpy ")
    assert stored.count(" (source ") == 1 and stored.count(", git ") <= 1  # named once
    # run.json says the same: a reader of the header sees the code, not the version number alone
    assert json.loads((run_dir / "run.json").read_text())["software_version"] == stored
    assert read_run(run_dir).software_version == stored
    (run_dir / "run.h5").unlink()  # the pieces alone: the same text
    assert read_run(run_dir).software_version == stored
