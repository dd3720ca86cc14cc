"""The catalog commands' failures: a damaged point is named and `catalog add` exits 1 (as
`export`), reading never creates a catalog, and an --out that cannot be written is one line
naming the path and the cause (exit 1, no traceback); a database URL the catalog does not
support is named with the ones it does; a predicted coefficient written as inf or nan is refused
naming the file, the line and the column (exit 2; it was taken), as is a column given twice."""

from __future__ import annotations

import shutil

from typer.testing import CliRunner

from orbitrig.catalog.store import Catalog
from orbitrig.cli import app
from orbitrig.store.reader import read_run

N_FITS = 8  # per point: four models on each load measuring system


def test_add_names_a_damaged_point_and_exits_1_adding_the_others(catalog_run, tmp_path):
    run = tmp_path / "runs" / "damaged"
    shutil.copytree(catalog_run, run)
    results = run / "points" / "0001" / "results.h5"
    results.write_bytes(results.read_bytes()[:100])
    res = CliRunner().invoke(app, ["catalog", "add", str(run)])
    assert res.exit_code == 1, res.output
    assert f"{run}: {N_FITS} rows" in res.stdout
    assert f"error: {run}: point 0001 skipped: results.h5 is damaged" in res.stderr
    rows = Catalog(f"sqlite:///{tmp_path / 'runs' / 'catalog.sqlite'}").rows()
    assert {r["point"] for r in rows} == {0} and len(rows) == N_FITS
    good = CliRunner().invoke(app, ["catalog", "add", str(catalog_run), "--db", f"sqlite:///{tmp_path / 'g.sqlite'}"])
    assert good.exit_code == 0 and good.stderr == "" and f"{2 * N_FITS} rows" in good.stdout


def test_reading_a_catalog_that_is_not_there_creates_nothing(tmp_path):
    for args in (["catalog", "list"], ["catalog", "export"], ["compare"]):
        res = CliRunner().invoke(app, [*args, "--runs", str(tmp_path)])
        assert res.exit_code == 1 and isinstance(res.exception, SystemExit), (args, res.output)
        assert f"{tmp_path / 'catalog.sqlite'}: no such file" in res.stderr and "Traceback" not in res.output
    assert list(tmp_path.iterdir()) == []


def test_a_catalog_added_among_the_runs_is_pointed_at_when_the_default_is_missing(tmp_path, monkeypatch):
    """`catalog add */` among the runs makes ./catalog.sqlite; `catalog list` there looks in
    runs/ by default: it says the one here and `--runs .`, and reads neither."""
    Catalog(f"sqlite:///{tmp_path / 'catalog.sqlite'}")  # as `catalog add a/ b/` run in tmp_path made it
    monkeypatch.chdir(tmp_path)
    for args in (["catalog", "list"], ["compare"]):
        res = CliRunner().invoke(app, args)
        assert res.exit_code == 1, (args, res.output)
        assert res.stderr.endswith(
            f"{tmp_path / 'runs' / 'catalog.sqlite'}: no such file (`orbitrig catalog add RUN` creates it); this"
            f" folder holds one, {(tmp_path / 'catalog.sqlite').resolve()}: give --runs .\n"
        ), res.stderr
    assert not (tmp_path / "runs").exists()
    listed = CliRunner().invoke(app, ["catalog", "list", "--runs", "."])
    assert listed.exit_code == 0 and listed.stdout.split()[0] == "run_id", listed.output


def test_an_out_that_cannot_be_written_is_named_with_its_cause(catalog_run, tmp_path):
    from orbitrig.catalog.rows import run_rows

    Catalog(f"sqlite:///{tmp_path / 'catalog.sqlite'}").add(run_rows(read_run(catalog_run)))
    a_file = tmp_path / "run.json"
    a_file.write_text("{}")
    runs = ["--runs", str(tmp_path)]
    res = CliRunner().invoke(app, ["compare", *runs, "--out", str(a_file)])
    assert res.exit_code == 1 and isinstance(res.exception, SystemExit), repr(res.exception)  # not an OSError
    assert f"error: {a_file}: " in res.stderr and "not a directory" in res.stderr and "Traceback" not in res.output
    assert a_file.read_text() == "{}"
    res = CliRunner().invoke(app, ["catalog", "export", *runs, "--out", str(a_file / "x.csv")])
    assert res.exit_code == 1
    assert (
        res.stderr == f"orbitrig catalog export: error: {a_file / 'x.csv'}: cannot write: {a_file} is not a directory\n"
    )
    res = CliRunner().invoke(app, ["catalog", "export", *runs, "--out", str(tmp_path / "no" / "x.csv")])
    assert res.exit_code == 1 and f"no folder {tmp_path / 'no'}" in res.stderr


def test_compare_takes_a_method_by_name_only(tmp_path):
    """--method is one of the estimators: nothing else reaches the catalog's query."""
    res = CliRunner().invoke(app, ["compare", "--runs", str(tmp_path), "--method", "ols or 1 = 1"])
    assert res.exit_code == 2 and "'ols or 1 = 1' is not one of 'ols', 'wls', 'tls', 'iv'" in res.stderr
    assert list(tmp_path.iterdir()) == []


def test_a_database_the_catalog_does_not_support_is_named_with_the_supported_ones(catalog_run, tmp_path):
    res = CliRunner().invoke(app, ["catalog", "add", str(catalog_run), "--db", "mysql://alice:secret@db.lab/fits"])
    assert res.exit_code != 0 and "Traceback" not in res.output, res.output
    assert "--db mysql://alice@db.lab/fits: database 'mysql' is not supported (use sqlite or postgresql)" in res.stderr
    assert "secret" not in res.output and list(tmp_path.iterdir()) == []


def test_a_prediction_that_is_not_finite_is_refused_naming_the_cell(catalog_run, tmp_path):
    from orbitrig.catalog.rows import run_rows

    Catalog(f"sqlite:///{tmp_path / 'catalog.sqlite'}").add(run_rows(read_run(catalog_run)))
    for cell in ("inf", "nan"):
        predicted = tmp_path / f"{cell}.csv"
        predicted.write_text(f"static_eccentricity,Kxx [N/m]\n0.0,3.3e7\n0.15,{cell}\n")
        args = ["compare", "--runs", str(tmp_path), "--against", "static_eccentricity", "--predicted", str(predicted)]
        res = CliRunner().invoke(app, [*args, "--out", str(tmp_path / "figures")])
        assert res.exit_code == 2, res.output
        assert f"error: {predicted}, line 3, column 'Kxx': '{cell}' is not a finite number" in res.stderr
    assert not (tmp_path / "figures").exists()


def test_a_predicted_column_given_twice_is_refused_naming_it(catalog_run, tmp_path):
    """The last of the two was taken: a prediction nobody wrote."""
    from orbitrig.catalog.rows import run_rows

    Catalog(f"sqlite:///{tmp_path / 'catalog.sqlite'}").add(run_rows(read_run(catalog_run)))
    predicted = tmp_path / "twice.csv"
    predicted.write_text("# model\nstatic_eccentricity,Kxx [N/m],Kxx [N/m]\n0.0,3.3e7,1\n")
    args = ["compare", "--runs", str(tmp_path), "--against", "static_eccentricity", "--predicted", str(predicted)]
    res = CliRunner().invoke(app, [*args, "--out", str(tmp_path / "figures")])
    assert res.exit_code == 2, res.output
    assert (
        res.stderr
        == f"orbitrig compare: error: {predicted}, line 2, column 'Kxx [N/m]': the column appears twice in the header\n"
    )
    assert not (tmp_path / "figures").exists()


def test_add_of_a_run_without_a_complete_point_adds_nothing_names_why_and_exits_1(catalog_run, tmp_path):
    """The rule of export, report and reduce for a run with nothing to work on, run by run: the
    run's points named with why, nothing added for it (no '0 rows'), the other runs added, exit 1
    (it printed '0 rows' and exited 0); no catalog file made when no run has a complete point."""
    from support.report_synthetic import write_synthetic_run

    cut = write_synthetic_run(tmp_path / "runs" / "cut", n_points=0, incomplete=2)
    db = tmp_path / "runs" / "catalog.sqlite"
    alone = CliRunner().invoke(app, ["catalog", "add", str(cut)])
    assert alone.exit_code == 1, alone.output
    assert alone.stdout == "" and not db.exists()
    assert alone.stderr.splitlines() == [
        f"{cut}: point 0000 not included: never completed (no commit record)",
        f"{cut}: point 0001 not included: never completed (no commit record)",
        f"orbitrig catalog add: error: {cut}: nothing added: the run has no complete operating point "
        "(each is named above with why)",
    ]
    both = CliRunner().invoke(app, ["catalog", "add", str(cut), str(catalog_run), "--db", f"sqlite:///{db}"])
    assert both.exit_code == 1, both.output
    assert both.stdout == f"{catalog_run}: {2 * N_FITS} rows\n"
    assert f"error: {cut}: nothing added" in both.stderr
    rows = Catalog(f"sqlite:///{db}").rows()
    assert {r["run_path"] for r in rows} == {str(catalog_run.resolve())} and len(rows) == 2 * N_FITS
    bad_db = CliRunner().invoke(app, ["catalog", "add", str(cut), "--db", "mysql://db.lab/fits"])
    assert bad_db.exit_code == 2 and "not supported" in bad_db.stderr  # bad usage stays 2 on such a run
