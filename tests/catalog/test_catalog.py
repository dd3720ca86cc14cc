"""The campaign catalog against real databases: an SQLite file and a PostgreSQL server."""

from __future__ import annotations

import asyncio
import csv
import io
import json
import logging
import threading

import pytest
from typer.testing import CliRunner

from orbitrig.catalog.errors import CatalogUsageError
from orbitrig.catalog.rows import run_rows
from orbitrig.catalog.store import Catalog
from orbitrig.cli import app
from orbitrig.service.catalog_feed import CatalogFeed
from orbitrig.store.reader import read_run

N_FITS = 8  # 2 load systems x 4 models per point


def test_add_twice_updates_never_duplicates(catalog, catalog_run):
    run = read_run(catalog_run)
    rows = run_rows(run)
    assert catalog.add(rows) == 2 * N_FITS
    rows[0]["operator"] = "bob"
    catalog.add(rows)
    stored = catalog.rows()
    assert len(stored) == 2 * N_FITS
    assert sorted(r["operator"] for r in stored).count("bob") == 1
    kc7 = next(r for r in stored if (r["point"], r["lms"], r["model"]) == (1, "piezo", "kc7"))
    result = run.points[1].identification("piezo", "kc7", "none").result
    assert kc7["Kxx"] == pytest.approx(result["coefficients"]["Kxx"], rel=1e-12)
    assert kc7["Kxx_U"] == pytest.approx(2 * result["std_errors"]["Kxx"], rel=1e-12)
    assert kc7["Dxx"] is None and kc7["u_basis"] == "statistical"
    assert (kc7["rig_id"], kc7["calibration_record"], kc7["started"]) == (
        "rigA",
        "2026-01-01.toml",
        "2026-11-26T10:00:00+00:00",
    )
    assert kc7["ended"] and kc7["run_path"] == str(catalog_run.resolve()) and kc7["run_id"].startswith("rigA@")
    refused = [r for r in stored if not r["ok"]]
    assert {r["model"] for r in refused} == {"kcd12"} and all(r["error"] for r in refused)


def test_where_filters_and_binds(catalog, catalog_run):
    catalog.add(run_rows(read_run(catalog_run)))
    eccentric = catalog.rows("static_eccentricity > 0.1")
    assert len(eccentric) == N_FITS and {r["static_eccentricity"] for r in eccentric} == {0.15}
    picked = catalog.rows("static_eccentricity >= 0 and lms = piezo and model == 'kcd11' and ok = true")
    assert {(r["point"], r["freq_dep"]) for r in picked} == {(0, "none"), (0, "power:1"), (1, "none"), (1, "power:1")}
    assert catalog.rows("adequacy_supported = false and lms != strain") != []
    assert catalog.rows("label = \"x' or '1'='1\"") == []  # a value is a bound parameter, never SQL
    assert len(catalog.rows()) == 2 * N_FITS


@pytest.mark.parametrize(
    "where, says",
    [
        ("static_eccentricity > 0.1; drop table fits", "cannot parse ';' at character 26"),
        ("static_eccentricity > 0.1x", "column 'static_eccentricity' takes a number, not '0.1x'"),
        ("1 = 1", "found '1' where a column name was expected"),
        ("nonsense > 1", "unknown column 'nonsense'"),
        ("point > 1 and", "found the end of the filter where a column name was expected"),
        ("point ~ 1", "cannot parse '~'"),
        ("point = 1.5", "column 'point' takes an integer, not '1.5'"),
        ("ok = maybe", "column 'ok' takes true or false, not 'maybe'"),
        ("lms = piezo or lms = strain", "found 'or' .*only.* after 'lms = piezo'"),
        ("point = 0 or 1=1", "found 'or' .* after 'point = 0'"),
        ("point = 0 OR point = 1", "found 'OR' "),
        ("not point = 0", "found 'not' .* where a column name was expected"),
        ("(point = 0)", r"found '\(' \(parentheses are not part of the grammar\)"),
        ("point = 0 and (lms = piezo)", r"found '\(' \(parentheses"),
        ("point = 0 lms = piezo", "found 'lms' after 'point = 0' where 'and' or the end was expected"),
        ("label = w1000rpm es0.1", "found 'es0.1' after 'label = w1000rpm'"),
        ("point =", "found the end of the filter after 'point =' where a value was expected"),
        ("Kxx >> 1", "found '>' after 'Kxx >' where a value was expected"),
        ("label = 'w1000rpm", "cannot parse an unclosed quote at character 9"),
    ],
)
def test_where_outside_the_grammar_is_refused(catalog, where, says):
    with pytest.raises(CatalogUsageError, match=says):
        catalog.rows(where)


def test_where_reads_tokens_not_glued_text(catalog, catalog_run):
    """Operators need no spaces, quoted text may hold spaces and grammar words, and a
    quoted number is converted to the column's type."""
    catalog.add(run_rows(read_run(catalog_run)))
    assert len(catalog.rows("static_eccentricity>0.1 and lms=piezo")) == N_FITS // 2
    power = catalog.rows("point = '1' and freq_dep = \"power:1\"")
    assert {(r["point"], r["lms"], r["model"]) for r in power} == {(1, "piezo", "kcd11"), (1, "strain", "kcd11")}
    assert catalog.rows("label = 'a or b' and lms = 'and'") == []


def test_where_on_a_column_holding_json_is_refused_saying_how_to_query_it(catalog, catalog_run):
    """orbit_hz holds a JSON list as text: `orbit_hz = 5` matched nothing, silently."""
    catalog.add(run_rows(read_run(catalog_run)))
    assert 5.0 in json.loads(catalog.rows()[0]["orbit_hz"])  # a point that was tested at 5 Hz
    for where in ("orbit_hz = 5", "orbit_hz = '[5.0]'", "coefficients_json != x"):
        res = CliRunner().invoke(app, ["catalog", "list", "--db", catalog.url, "--where", where])
        assert res.exit_code == 2 and "Traceback" not in res.output, res.output
        column = where.split()[0]
        assert f"--where {where!r}: column {column!r} holds a JSON " in res.stderr
    assert "columns of their own (Kxx ... Dyy" in res.stderr  # coefficients_json's
    res = CliRunner().invoke(app, ["catalog", "list", "--db", catalog.url, "--where", "orbit_hz = 5"])
    assert "spin_rpm" in res.stderr and "catalog export --format json" in res.stderr


def test_cli_add_list_export(catalog_run):
    runner, runs = CliRunner(), catalog_run.parent
    for _ in range(2):
        res = runner.invoke(app, ["catalog", "add", str(catalog_run)])
        assert res.exit_code == 0, res.output
    assert (runs / "catalog.sqlite").is_file()
    listed = runner.invoke(
        app,
        [
            "catalog",
            "list",
            "--runs",
            str(runs),
            "--where",
            "static_eccentricity > 0.1",
            "--columns",
            "point,model,Kxx_U",
        ],
    )
    assert listed.exit_code == 0 and len(listed.stdout.strip().splitlines()) == 1 + N_FITS
    assert listed.stderr == "units: Kxx_U N/m (SI, as stored)\n"  # the table's numbers are SI, not MN/m
    listed = runner.invoke(app, ["catalog", "list", "--runs", str(runs), "--columns", "point,spin_rpm,Cxy,Dyy_U"])
    assert listed.stderr == "units: Cxy N s/m; Dyy_U kg (SI, as stored)\n"  # spin_rpm says its own
    exported = runner.invoke(app, ["catalog", "export", "--runs", str(runs)])
    table = list(csv.DictReader(io.StringIO(exported.output)))
    assert len(table) == 2 * N_FITS and "Kxx [N/m]" in table[0] and "recess_pressure [Pa]" in table[0]
    assert "orbit_hz" not in table[0] and json.loads(table[0]["orbit_hz [Hz]"])  # the unit, like the others
    out = runs / "cat.json"
    res = runner.invoke(app, ["catalog", "export", "--runs", str(runs), "--format", "json", "--out", str(out)])
    objects = json.loads(out.read_text())
    assert res.exit_code == 0 and len(objects) == 2 * N_FITS
    hz = [float(v) for v in json.loads(table[0]["orbit_hz [Hz]"])]
    assert objects[0]["orbit_hz"] == hz and all(isinstance(v, float) for v in objects[0]["orbit_hz"])  # a list
    assert objects[0]["coefficients_json"]["values"]["Kxx"] == float(table[0]["Kxx [N/m]"])  # an object
    bad = runner.invoke(app, ["catalog", "list", "--runs", str(runs), "--where", "Kxx >> 1"])
    assert bad.exit_code == 2 and "Kxx" in bad.output and "Traceback" not in bad.output
    bad = runner.invoke(app, ["catalog", "list", "--runs", str(runs), "--where", "lms = piezo or lms = strain"])
    assert bad.exit_code == 2 and "found 'or'" in bad.output and "Traceback" not in bad.output
    bad = runner.invoke(app, ["catalog", "add", str(runs / "nowhere")])
    assert bad.exit_code == 2


def test_service_feed_adds_points_and_survives_a_broken_catalog(catalog_run, tmp_path, caplog):
    url = f"sqlite:///{tmp_path / 'feed.sqlite'}"

    async def feed(target: CatalogFeed):
        for point in (0, 1, 1):  # a point reported twice stays one set of rows
            target.point_completed(catalog_run, point)
        assert await asyncio.to_thread(target.finish, 30) == []
        assert target.added + target.failed == 3

    good = CatalogFeed(url)
    asyncio.run(feed(good))
    assert len(Catalog(url).rows()) == 2 * N_FITS
    broken = CatalogFeed(f"sqlite:///{tmp_path / 'no' / 'such' / 'dir.sqlite'}")
    with caplog.at_level(logging.WARNING, logger="orbitrig.service.catalog"):
        asyncio.run(feed(broken))
    assert broken.added == 0 and broken.failed == 3 and "not added" in caplog.text


def test_the_same_rows_added_at_once_by_two_writers(catalog, catalog_run):
    """The service's feed and `catalog add` of one run overlap: both succeed, one set of rows."""
    rows = run_rows(read_run(catalog_run))
    failures: list[str] = []
    for _ in range(5):
        barrier = threading.Barrier(2)

        def add(barrier: threading.Barrier) -> None:
            writer = Catalog(catalog.url)
            barrier.wait()
            try:
                writer.add(rows)
            except Exception as err:  # noqa: BLE001 - collected and asserted
                failures.append(str(err))
            finally:
                writer.close()

        threads = [threading.Thread(target=add, args=(barrier,)) for _ in range(2)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
    assert failures == [] and len(catalog.rows()) == 2 * N_FITS


def test_an_add_larger_than_one_statement_can_bind(catalog, catalog_run):
    """12 000 rows bind more than PostgreSQL's 65 535 parameters in one statement: written in batches."""
    base = run_rows(read_run(catalog_run))
    many = [{**row, "point": 1000 * n + row["point"]} for n in range(12_000 // len(base)) for row in base]
    assert catalog.add(many) == len(many) == 12_000
    many[-1]["operator"] = "carol"
    assert catalog.add(many[-600:]) == 600
    stored = catalog.rows("operator = carol")
    assert len(catalog.rows()) == 12_000 and [r["point"] for r in stored] == [many[-1]["point"]]
