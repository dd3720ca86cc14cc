from __future__ import annotations

import pytest

from support.report_synthetic import write_synthetic_run


@pytest.fixture(scope="session")
def synthetic_run(tmp_path_factory):
    """Two complete points and one incomplete one, known coefficients, 0.1 % force noise."""
    return write_synthetic_run(tmp_path_factory.mktemp("synthetic") / "run")


@pytest.fixture(scope="session")
def synthetic_report(synthetic_run):
    """`orbitrig report DIR --point 1 --formats png` on the synthetic run (PDF and SVG: test_report_journal)."""
    from typer.testing import CliRunner

    from orbitrig.cli import app

    result = CliRunner().invoke(app, ["report", str(synthetic_run), "--point", "1", "--formats", "png"])
    page = synthetic_run / "plots" / "index.html"
    result.page = page.read_text(encoding="utf-8") if page.exists() else ""  # later reports rewrite it
    return result
