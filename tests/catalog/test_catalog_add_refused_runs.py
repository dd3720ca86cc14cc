"""`catalog add runs/*/` adds every readable run: a folder the glob matches that is no run, or a
run whose run.json cannot be read, is named with why and the others are added (exit 1); when no
RUN is added the exit status is 2 and no catalog file is made."""

from __future__ import annotations

import shutil

from typer.testing import CliRunner

from orbitrig.catalog.store import Catalog
from orbitrig.cli import app

N_FITS = 8  # per point: four models on each load measuring system


def test_add_of_a_glob_adds_the_readable_runs_and_names_the_others(catalog_run, tmp_path):
    runs = tmp_path / "runs"
    shutil.copytree(catalog_run, runs / "b-good")
    shutil.copytree(catalog_run, runs / "a-broken")
    (runs / "a-broken" / "run.json").write_text("{not json")
    (runs / "c-figures").mkdir()
    (runs / "c-figures" / "plot.png").write_bytes(b"png")
    matched = sorted(str(p) + "/" for p in runs.iterdir())  # runs/*/
    res = CliRunner().invoke(app, ["catalog", "add", *matched])
    assert res.exit_code == 1, res.output
    assert f"{runs / 'b-good'}: {2 * N_FITS} rows" in res.stdout
    assert (
        f"error: {runs / 'a-broken'}: not added: {runs / 'a-broken' / 'run.json'}: not a readable run header"
        in res.stderr
    )
    assert f"error: {runs / 'c-figures'}: not added: not an orbitrig run directory" in res.stderr
    assert "Traceback" not in res.output
    rows = Catalog(f"sqlite:///{runs / 'catalog.sqlite'}", create=False).rows()
    assert len(rows) == 2 * N_FITS and {r["run_path"] for r in rows} == {str(runs / "b-good")}
    none = CliRunner().invoke(
        app, ["catalog", "add", matched[0], matched[2], "--db", f"sqlite:///{tmp_path / 'n.sqlite'}"]
    )
    assert none.exit_code == 2, none.output
    assert none.stderr.count("not added") == 2 and not (tmp_path / "n.sqlite").exists()


def test_a_folder_of_runs_given_as_a_run_says_to_give_its_runs(catalog_run, tmp_path):
    """`catalog add served` (the runs folder of `orbitrig serve --out`, whose runs are its
    folders) names the runs inside and how to give them, not only that it is no run."""
    served = tmp_path / "served"
    for name in ("20261206T192258.007Z-demo", "20261206T193000.000Z-demo"):
        shutil.copytree(catalog_run, served / name)
    (served / "notes").mkdir()
    res = CliRunner().invoke(app, ["catalog", "add", str(served), "--db", f"sqlite:///{tmp_path / 'c.sqlite'}"])
    assert res.exit_code == 2, res.output
    assert res.stderr == (
        f"orbitrig catalog add: error: {served}: not added: not an orbitrig run directory: no run.h5 (nor run.json)"
        f" in it; it holds runs in its folders (20261206T192258.007Z-demo, 20261206T193000.000Z-demo): give"
        f" those, e.g. {served / '20261206T192258.007Z-demo'} or {served}/*/\n"
    )
    empty = CliRunner().invoke(
        app, ["catalog", "add", str(served / "notes"), "--db", f"sqlite:///{tmp_path / 'c.sqlite'}"]
    )
    assert empty.exit_code == 2 and empty.stderr.endswith("no run.h5 (nor run.json) in it\n"), empty.stderr
