"""What the commands over a run say when the disk says no: `report` and `reduce` on a full
or read-only disk give one line and exit 1 (a run whose run.h5 does not fit:
test_room_before_point); `export` and `report` name every point they
skip (a damaged block) and exit 1 when one was asked for."""

from __future__ import annotations

import re

import shutil
import subprocess

import pytest
from typer.testing import CliRunner

from orbitrig.cli import app
from orbitrig.store.reader import read_run

from support.cli_helpers import orbitrig
from support.small_disk import mounted_tmpfs
from support.store_checks import fill, small_matrix

pytestmark = pytest.mark.timeout(240)


@pytest.fixture
def small_disk(tmp_path):
    """A 2 MB tmpfs: room for one small point (its pieces, about 330 kB, and their run.h5 copy)."""
    with mounted_tmpfs(tmp_path / "disk", "2m") as mnt:
        yield mnt


def _one_line_error(r: subprocess.CompletedProcess, says: str) -> None:
    assert r.returncode == 1, r.stdout + r.stderr
    assert "Traceback" not in r.stderr, r.stderr
    errors = [line for line in r.stderr.splitlines() if re.match(r"orbitrig [\w ]+: error: ", line)]
    assert len(errors) == 1 and says in errors[0], r.stderr


def test_full_or_read_only_disks_fail_in_one_line(small_disk, tmp_path):
    matrix = tmp_path / "one.toml"
    matrix.write_text(small_matrix("one", revolutions=20, spin_rpm=(1000.0,)))
    out = small_disk / "run"
    r = orbitrig("sweep", "--sim", "--matrix", str(matrix), "--out", str(out), timeout=180, columns=None)
    text = " ".join((r.stdout + r.stderr).split())  # the summary is wrapped to the terminal
    assert r.returncode == 0, text
    assert [p.complete for p in read_run(out).points] == [True]

    fill(small_disk)  # now nothing fits
    for args, says in (
        (["reduce", str(out), "--model", "kc8"], "No space left on device"),
        (["report", str(out), "--figures", "coefficients"], "No space left on device"),
    ):
        _one_line_error(orbitrig(*args, timeout=120, columns=None), says)
    (small_disk / "filler").unlink()
    subprocess.run(["mount", "-o", "remount,ro", str(small_disk)], check=True)
    for args in (["reduce", str(out), "--model", "kc8"], ["report", str(out), "--figures", "coefficients"]):
        _one_line_error(
            orbitrig(*args, timeout=120, columns=None),
            "Read-only file system",
        )


def _damage(run, name: str) -> None:
    path = run / "points" / "0000" / name
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0xFF
    path.write_bytes(bytes(data))


def test_export_and_report_name_a_point_with_a_damaged_block(synthetic, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(synthetic, run)
    _damage(run, "03_fwd.h5")
    runner = CliRunner()
    r = runner.invoke(app, ["export", str(run), "--out", str(tmp_path / "all")])
    assert r.exit_code == 1, r.output
    assert "error: point 0000 skipped: 03_fwd.h5 is damaged" in r.stderr
    assert "point 0002 not included: never completed" in r.stderr  # the stopped run's last point: a note
    written = sorted(p.name for p in (tmp_path / "all").iterdir())
    assert [n for n in written if n.startswith("point_")] == ["point_0001_piezo.csv", "point_0001_strain.csv"]
    assert not [n for n in written if "_0000" in n] and "coefficients.csv" in written  # nothing of point 0
    r = runner.invoke(app, ["export", str(run), "--point", "1", "--out", str(tmp_path / "one")])
    assert r.exit_code == 0 and "skipped" not in r.stderr, r.output
    r = runner.invoke(
        app, ["export", str(run), "--point", "0", "--point", "1", "--format", "mat", "--out", str(tmp_path / "mat")]
    )
    assert r.exit_code == 1 and "point 0000 skipped: 03_fwd.h5 is damaged" in r.stderr, r.output
    r = runner.invoke(app, ["report", str(run), "--figures", "coefficients"])
    assert r.exit_code == 1 and "error: point 0000 skipped: 03_fwd.h5 is damaged" in r.stderr, r.output
    assert list((run / "plots").glob("coefficients_0001*.png")) and not list((run / "plots").glob("*_0000*.png"))


def test_export_of_an_undamaged_stopped_run_notes_the_point_never_completed(synthetic, tmp_path):
    r = CliRunner().invoke(app, ["export", str(synthetic), "--out", str(tmp_path / "x")])
    assert r.exit_code == 0 and "point 0002 not included: never completed" in r.stderr, r.output
    r = CliRunner().invoke(app, ["export", str(synthetic), "--point", "2", "--out", str(tmp_path / "y")])
    assert r.exit_code == 1 and "error: point 0002 skipped: never completed" in r.stderr, r.output


def test_a_point_cut_before_its_settings_were_stored_is_noted_not_an_error(synthetic, tmp_path):
    """A kill between creating a point's folder and storing its settings leaves an empty
    folder: nothing of that point is stored and nothing is damaged (strace kill at fsync 23)."""
    run = tmp_path / "run"
    shutil.copytree(synthetic, run)
    (run / "points" / "0003").mkdir()
    r = CliRunner().invoke(app, ["export", str(run), "--out", str(tmp_path / "x")])
    assert r.exit_code == 0 and "point 0003 not included: never begun (no settings record)" in r.stderr, r.output
    r = CliRunner().invoke(app, ["export", str(run), "--point", "3", "--out", str(tmp_path / "y")])
    assert r.exit_code == 1 and "error: point 0003 skipped: never begun" in r.stderr, r.output
    (run / "points" / "0004").mkdir()
    (run / "points" / "0004" / "point.json").write_text("{torn")  # a settings record that is there but torn
    r = CliRunner().invoke(app, ["export", str(run), "--out", str(tmp_path / "z")])
    assert r.exit_code == 1 and "unreadable point settings" in r.stderr, r.output
