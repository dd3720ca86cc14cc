"""Temporary files are created new (O_CREAT | O_EXCL | O_NOFOLLOW): a leftover NAME.tmp is
removed, a symbolic link planted there is never followed, so its target keeps its bytes."""

from __future__ import annotations

import os
import shutil

import pytest
from typer.testing import CliRunner

from orbitrig.cli import app
from orbitrig.store.durable import remove, write_atomic
from orbitrig.store.errors import StorageError

VICTIM = b"precious: must not be overwritten\n"


def _plant(link, victim):
    """A symbolic link at `link` to a file `victim` holding VICTIM; returns the victim."""
    victim.write_bytes(VICTIM)
    os.symlink(victim, link)
    return victim


def test_write_atomic_removes_a_leftover_and_never_follows_a_link(tmp_path):
    path = tmp_path / "coefficients.csv"
    (tmp_path / "coefficients.csv.tmp").write_bytes(b"x" * 10_000)  # a kill's leftover
    assert write_atomic(path, b"new\n")["size"] == 4 and path.read_bytes() == b"new\n"
    victim = _plant(tmp_path / "coefficients.csv.tmp", tmp_path / "victim.txt")
    write_atomic(path, b"newer\n")
    assert victim.read_bytes() == VICTIM
    assert path.read_bytes() == b"newer\n" and not path.is_symlink()
    assert not os.path.lexists(tmp_path / "coefficients.csv.tmp")


def test_a_dangling_link_at_the_temporary_name_creates_nothing_at_its_target(tmp_path):
    target = tmp_path / "elsewhere" / "created.txt"
    target.parent.mkdir()
    os.symlink(target, tmp_path / "run.h5.tmp")
    write_atomic(tmp_path / "run.h5", b"h5")
    assert not target.exists() and (tmp_path / "run.h5").read_bytes() == b"h5"


def test_a_file_on_the_way_is_named_as_the_cause_not_a_leftover(tmp_path):
    """A path under a file (a mistyped --out): the error is that the temporary file cannot be
    created there (not a directory), not that a leftover could not be removed."""
    (tmp_path / "a_file").write_text("x")
    with pytest.raises(StorageError) as err:
        write_atomic(tmp_path / "a_file" / "out.csv", b"data")
    assert (
        str(err.value) == f"{tmp_path / 'a_file' / 'out.csv.tmp'}: cannot create: NotADirectoryError: Not a directory"
    )


@pytest.mark.parametrize("fmt", ["csv", "mat", "h5"])
def test_export_into_a_fresh_out_with_planted_links(synthetic, tmp_path, fmt):
    out = tmp_path / "out"
    out.mkdir()
    names = {"csv": ["coefficients.csv", "point_0000_piezo.csv"], "mat": ["run.mat"], "h5": ["run.h5"]}[fmt]
    victims = [_plant(out / f"{n}.tmp", tmp_path / f"victim_{n}") for n in names]
    r = CliRunner().invoke(app, ["export", str(synthetic), "--format", fmt, "--out", str(out)])
    assert r.exit_code == 0 and "point 0002 not included: never completed" in r.stderr, r.output
    for victim in victims:
        assert victim.read_bytes() == VICTIM
    for n in names:
        assert (out / n).is_file() and not (out / n).is_symlink() and (out / n).stat().st_size > 100


def test_reduce_and_report_never_follow_a_planted_link(synthetic, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(synthetic, run, symlinks=True)
    (run / "plots").mkdir()
    victims = [
        _plant(run / "reduce_kc8_none_ols.csv.tmp", tmp_path / "victim_a"),
        _plant(run / "plots" / "index.html.tmp", tmp_path / "victim_b"),
    ]
    r = CliRunner().invoke(app, ["reduce", str(run), "--model", "kc8"])
    assert r.exit_code == 0, r.output
    r = CliRunner().invoke(app, ["report", str(run), "--point", "1", "--figures", "coefficients"])
    assert r.exit_code == 0, r.output
    assert all(v.read_bytes() == VICTIM for v in victims)
    assert (run / "reduce_kc8_none_ols.csv").read_text().startswith("point,label,")
    assert "<html" in (run / "plots" / "index.html").read_text()


def test_the_append_only_logs_refuse_a_planted_link(tmp_path):
    from orbitrig.store.durable import append_lines
    from orbitrig.store.errors import StorageError

    victim = _plant(tmp_path / "journal.jsonl", tmp_path / "victim.txt")
    with pytest.raises(StorageError, match="journal.jsonl"):
        append_lines(tmp_path / "journal.jsonl", ['{"k": "status"}'])
    assert victim.read_bytes() == VICTIM


def test_remove_takes_a_file_or_a_link_away_and_names_what_it_cannot_remove(tmp_path):
    """durable.remove (a report's old figures, its PDF, a figure record): a file that is not
    there is no failure, a symbolic link goes without its target, and a name that cannot be
    removed (a folder there) is the StorageError naming it."""
    remove(tmp_path / "absent.png")
    (tmp_path / "old.png").write_bytes(b"png")
    remove(tmp_path / "old.png")
    assert not (tmp_path / "old.png").exists()
    victim = _plant(tmp_path / "report.pdf", tmp_path / "victim.txt")
    remove(tmp_path / "report.pdf")
    assert not os.path.lexists(tmp_path / "report.pdf") and victim.read_bytes() == VICTIM
    (tmp_path / "summary.png").mkdir()
    with pytest.raises(StorageError, match=r"summary.png: cannot remove: "):
        remove(tmp_path / "summary.png")
    assert (tmp_path / "summary.png").is_dir()
