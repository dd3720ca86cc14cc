"""A run resumed with other software says so where its data goes: each point's point.json and its
/points/PPPP group name the software that measured it, and run.h5's ``software_versions`` lists
every one (two here) where the run's own ``software_version`` names only the starting one.

Real parts: `orbitrig sweep --sim` of a two-point matrix from a copy of this source tree in a
subprocess, killed (SIGKILL) once point 0000 is committed; then the copy's ``__version__`` changed
(orbitrig.run.provenance.software_version: version number and the sources' digest) and the run
resumed from it to its end. run.h5 read with h5py.
"""

from __future__ import annotations

import html
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import h5py
import pytest

from support.cli_helpers import orbitrig, orbitrig_started, reaped
from support.paths import ROOT
from support.store_checks import small_matrix

pytestmark = pytest.mark.timeout(300)
MATRIX = small_matrix("versions", 20, spin_rpm=(1000.0, 2000.0))


def source_copy(dest: Path) -> Path:
    """The tracked files of this tree, but tests, docs and examples, in `dest`."""
    files = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True).stdout
    for name in files.split():
        if name.split("/")[0] in ("tests", "docs", "examples") or not (ROOT / name).is_file():
            continue
        (dest / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(ROOT / name, dest / name)
    return dest


def sweep(src: Path, out: Path, *args: str) -> subprocess.Popen:
    """`orbitrig sweep --sim` of the copy at ``src`` (only it on PYTHONPATH)."""
    args = ("sweep", "--sim", "--out", str(out), "--operator", "ada", *args)
    return orbitrig_started(*args, cwd=src, env={"PYTHONPATH": str(src)}, stdin=subprocess.PIPE)


def version_of(src: Path) -> str:
    code = "from orbitrig.run.provenance import software_version; print(software_version())"
    env = {**os.environ, "PYTHONPATH": str(src)}
    return subprocess.run(
        [sys.executable, "-c", code], cwd=src, env=env, capture_output=True, text=True, check=True
    ).stdout.strip()


def test_points_measured_by_two_versions_say_which_and_run_h5_lists_both(tmp_path):
    src = source_copy(tmp_path / "src")
    (tmp_path / "m.toml").write_text(MATRIX)
    out = tmp_path / "run"
    first = version_of(src)
    with reaped(sweep(src, out, "--matrix", str(tmp_path / "m.toml"), "--speedup", "20")) as proc:
        deadline = time.monotonic() + 120
        while not (out / "points/0000/complete.json").is_file():
            assert proc.poll() is None, proc.stderr.read() if proc.stderr else ""
            assert time.monotonic() < deadline, "point 0000 never committed"
            time.sleep(0.01)
    assert not (out / "points/0001/complete.json").is_file()  # point 0001 is left to the resume
    init = src / "orbitrig/__init__.py"
    init.write_text(init.read_text().replace('__version__ = "0.1.0"', '__version__ = "0.1.1"'))
    second = version_of(src)
    assert second != first and second.startswith("orbitrig 0.1.1 (source ")
    with reaped(sweep(src, out, "--resume", "--speedup", "20")) as resumed:
        _, err = resumed.communicate(timeout=200)
    assert resumed.returncode == 0, err
    settings = [json.loads((out / f"points/{p}/point.json").read_text()) for p in ("0000", "0001")]
    assert [s["software"] for s in settings] == [first, second]
    with h5py.File(out / "run.h5", "r") as f:
        assert f["points/0000"].attrs["software"] == first and f["points/0001"].attrs["software"] == second
        assert json.loads(f.attrs["software_versions"]) == [first, second]
        assert str(f.attrs["software_version"]).startswith(first + ",")  # the run's: the one it started with
    # an export and the report list both, with the points each measured
    for args in (("export", str(out)), ("report", str(out), "--figures", "lms")):
        p = orbitrig(*args, timeout=200, columns=None)
        assert p.returncode == 0, p.stdout + p.stderr
    provenance = (out / "export/provenance.csv").read_text()
    assert f"software_versions,{first}; {second}\n" in provenance.replace('"', ""), provenance
    page = (out / "plots/index.html").read_text()
    said = f"its points measured by 2 versions: {first} (points 0000); {second} (points 0001)"
    assert html.escape(said) in page or said in page, page[:3000]
