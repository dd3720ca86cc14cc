"""A csv export into a folder an earlier csv export wrote leaves only current files: the
export lists what it wrote in ``csv_manifest.txt`` and removes the earlier export's files it
did not write again (named on standard error), never a file the exporter did not write; a
folder without a manifest keeps its files and the look-alikes are named. A run without a
complete operating point exports nothing and exits 1 (real `orbitrig` subprocess)."""

from __future__ import annotations

import csv

import pytest

from orbitrig.store.export import export_run
from orbitrig.store.export_manifest import MANIFEST, listed

from support.cli_helpers import orbitrig


@pytest.fixture(scope="module")
def three(tmp_path_factory):
    """Three complete points, no incomplete one."""
    from support.report_synthetic import write_synthetic_run

    return write_synthetic_run(tmp_path_factory.mktemp("three") / "run", n_points=3, incomplete=0, seed=3)


def _orbitrig(*args):
    return orbitrig(*map(str, args))


def _points_in(folder):
    return sorted(p.name for p in folder.glob("point_*.csv"))


def test_a_later_export_of_fewer_points_removes_the_earlier_ones(three, synthetic, tmp_path):
    out = tmp_path / "out"
    first = export_run(three, "csv", out)
    assert _points_in(out) == [f"point_000{i}_{lms}.csv" for i in range(3) for lms in ("piezo", "strain")]
    assert listed(out) == {p.name for p in first.files}
    (out / "notes.txt").write_text("mine")  # the user's own files stay
    (out / "point_0002_mine.csv").write_text("mine")
    second = export_run(synthetic, "csv", out)  # another run, two points
    written = {p.name for p in second.files}
    assert _points_in(out) == sorted(
        ["point_0002_mine.csv"] + [f"point_000{i}_{lms}.csv" for i in range(2) for lms in ("piezo", "strain")]
    )
    assert [p.name for p in out.glob("*_0002_*")] == ["point_0002_mine.csv"]  # covariance_, derived_ too
    assert listed(out) == written and MANIFEST not in written
    assert set(p.name for p in out.iterdir()) == written | {MANIFEST, "notes.txt", "point_0002_mine.csv"}
    removed = [n for n in second.selection.notes if n.startswith("removed ")]
    assert f"removed {out / 'point_0002_piezo.csv'}: written by the earlier csv export, not by this one" in removed
    with open(out / "coefficients.csv", newline="") as fh:
        assert {r["point"] for r in csv.DictReader(fh)} == {"0", "1"}


def test_the_cli_names_what_it_removed_and_a_point_filter_removes_too(three, tmp_path):
    out = tmp_path / "out"
    assert _orbitrig("export", three, "--out", out).returncode == 0
    done = _orbitrig("export", three, "--out", out, "--point", "1")
    assert done.returncode == 0, done.stderr
    assert _points_in(out) == ["point_0001_piezo.csv", "point_0001_strain.csv"]
    assert f"removed {out / 'point_0000_piezo.csv'}: written by the earlier csv export" in done.stderr
    assert sorted(listed(out)) == sorted(line.rsplit("/", 1)[1] for line in done.stdout.split())


def test_a_folder_without_manifest_keeps_its_files_and_names_look_alikes(synthetic, tmp_path):
    out = tmp_path / "old"
    out.mkdir()
    (out / "point_0007_piezo.csv").write_text("from an export before manifests")
    done = export_run(synthetic, "csv", out)
    assert (out / "point_0007_piezo.csv").read_text() == "from an export before manifests"
    assert (
        f"{out / 'point_0007_piezo.csv'} was not written by this export (no earlier manifest): left as it is"
        in done.selection.notes
    )


def test_a_manifest_never_removes_what_an_export_does_not_write(synthetic, tmp_path):
    out = tmp_path / "out"
    export_run(synthetic, "csv", out)
    (out / "elsewhere.txt").write_text("keep")
    (tmp_path / "outside.csv").write_text("keep")
    with open(out / MANIFEST, "a", encoding="utf-8") as fh:  # a manifest edited by hand
        fh.write("elsewhere.txt\n../outside.csv\n")
    export_run(synthetic, "csv", out)
    assert (out / "elsewhere.txt").read_text() == "keep" and (tmp_path / "outside.csv").read_text() == "keep"


@pytest.mark.parametrize("fmt", ["csv", "mat", "ross"])
def test_a_run_without_a_complete_point_exports_nothing_and_exits_1(tmp_path, fmt):
    from support.report_synthetic import write_synthetic_run

    run = write_synthetic_run(tmp_path / "run", n_points=0, incomplete=2)
    done = _orbitrig("export", run, "--format", fmt)
    assert done.returncode == 1, done.stdout + done.stderr
    assert f"nothing exported: no folder written ({run / 'export'} not made)" in done.stdout
    assert "error: nothing exported: the run has no complete operating point" in done.stderr
    assert "point 0000 not included: never completed" in done.stderr
    assert "point 0001 not included: never completed" in done.stderr
    assert not (run / "export").exists()
