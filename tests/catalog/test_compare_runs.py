"""`orbitrig compare RUN RUN`: two runs compared by themselves, read from their folders, with no
catalog made or read (the lab's catalog, --db or $ORBITRIG_CATALOG, holds other runs of the same
matrix, which --where, a conjunction, could not leave out). It said 'Got unexpected extra
argument(s)'."""

from __future__ import annotations

import json
import shutil

from typer.testing import CliRunner

from orbitrig.cli import app


def test_two_runs_are_compared_from_their_folders(catalog_run, tmp_path):
    runs = tmp_path / "runs"
    first, second = shutil.copytree(catalog_run, runs / "a"), runs / "b"
    shutil.copytree(catalog_run, second)
    header = json.loads((second / "run.json").read_text())
    header["created"] = "2026-11-27T09:00:00.000Z"  # another run: its own run_id, rig@created
    (second / "run.json").write_text(json.dumps(header))
    lab = f"sqlite:///{tmp_path / 'lab.sqlite'}"  # not there: reading it would be refused
    runner = CliRunner()

    drawn = runner.invoke(
        app, ["compare", str(first), str(second), "--out", str(tmp_path / "fig")], env={"ORBITRIG_CATALOG": lab}
    )

    assert drawn.exit_code == 0, drawn.output
    assert drawn.stdout.splitlines() == [str(tmp_path / "fig" / "compare.png"), str(tmp_path / "fig" / "compare.pdf")]
    assert not (tmp_path / "lab.sqlite").exists() and not (runs / "catalog.sqlite").exists()
    narrowed = runner.invoke(app, ["compare", str(first), str(second), "--where", "static_eccentricity = 0.7"])
    assert narrowed.exit_code == 2
    assert narrowed.stderr.strip() == (
        "orbitrig compare: error: no rows of the runs given for piezo kcd11 none ols where static_eccentricity = 0.7; "
        "their 4 rows of that fit kind have static_eccentricity 0, 0.15"  # 2 points of each RUN
    )
    missing = runner.invoke(app, ["compare", str(first), str(runs / "c")])
    assert missing.exit_code == 2
    assert missing.stderr.startswith(f"orbitrig compare: error: {runs / 'c'}: no such directory")


def test_a_damaged_point_of_a_run_is_named_and_the_exit_status_is_1(catalog_run, tmp_path):
    """As export, report, reduce and catalog add: the other points are drawn."""
    run = shutil.copytree(catalog_run, tmp_path / "runs" / "a")
    (run / "points" / "0001" / "results.h5").write_bytes(b"cut")
    done = CliRunner().invoke(app, ["compare", str(run), "--out", str(tmp_path / "fig")])
    assert done.exit_code == 1, done.output
    assert f"orbitrig compare: error: {run}: point 0001 skipped: results.h5 is damaged" in done.stderr
    assert (tmp_path / "fig" / "compare.png").is_file()
