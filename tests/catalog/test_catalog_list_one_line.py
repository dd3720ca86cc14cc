"""`orbitrig catalog list` prints one line per catalog row, also for a refused model whose
stored message spans lines (a rank-deficiency report of 17 lines): its cell is the message
joined with ' | ', as coefficients.csv's `error` column has it; the rows stay in the database
unchanged (the export gives the whole text)."""

from __future__ import annotations

import json

from typer.testing import CliRunner

from orbitrig.catalog.store import Catalog
from orbitrig.cli import app


def test_list_shows_a_multi_line_refusal_on_its_row(catalog_run, postgres_server, tmp_path):
    cat = Catalog(postgres_server)
    with cat.engine.begin() as conn:  # the server lives for the session: start empty
        conn.exec_driver_sql("DELETE FROM fits")
    cat.close()
    runner = CliRunner()
    added = runner.invoke(app, ["catalog", "add", "--db", postgres_server, str(catalog_run)])
    assert added.exit_code == 0, added.output
    listed = runner.invoke(
        app,
        ["catalog", "list", "--db", postgres_server, "--where", "ok = false", "--columns", "point,lms,model,error"],
    )
    assert listed.exit_code == 0, listed.output
    lines = listed.stdout.rstrip("\n").splitlines()
    assert lines[0].split() == ["point", "lms", "model", "error"]
    assert len(lines) == 1 + 4  # two points x two load systems refuse kcd12 poly:8
    for line in lines[1:]:
        point, lms, model, error = line.split(None, 3)
        assert point in ("0", "1") and lms in ("piezo", "strain") and model == "kcd12"
        assert error.startswith("kcd12 with freq-dep poly:8 (80 coefficients) cannot be identified") and " | " in error
    everything = runner.invoke(app, ["catalog", "list", "--db", postgres_server])
    assert everything.exit_code == 0 and len(everything.stdout.rstrip("\n").splitlines()) == 1 + 16
    out = tmp_path / "all.json"
    runner.invoke(app, ["catalog", "export", "--db", postgres_server, "--format", "json", "--out", str(out)])
    stored = [r["error"] for r in json.loads(out.read_text()) if not r["ok"]]
    assert len(stored) == 4 and all(e.count("\n") >= 10 for e in stored)  # the database keeps the message as it was
    joined = " | ".join(p.strip() for p in stored[0].splitlines() if p.strip())
    assert any(line.split(None, 3)[3] == joined for line in lines[1:])
