from __future__ import annotations

import pytest

from support.cli_helpers import orbitrig
from support.report_figures import KINDS, drawn_figures
from support.report_synthetic import write_synthetic_run
from support.sweep_helpers import demo_text


@pytest.fixture(scope="session")
def sweep_run(tmp_path_factory):
    """A run written by the real sweep on the simulator (`orbitrig sweep --sim --sim-config
    config/sim/clean.toml --matrix SMALL --out DIR`: the clean scenario, the demo matrix with fewer
    revolutions per block and one frequency-dependent model more)."""
    base = tmp_path_factory.mktemp("sweep")
    text = demo_text("report-small", 10)
    text += '\n[[models]]\nmodel = "kcd11"\nfreq_dep = "power:1"\n'
    matrix = base / "small.toml"
    matrix.write_text(text)
    out = base / "run"
    p = orbitrig("sweep", "--sim", "--sim-config", "config/sim/clean.toml", "--matrix", str(matrix), "--out", str(out))
    assert p.returncode == 0, p.stdout + p.stderr
    return out


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


@pytest.fixture(scope="session")
def synthetic_figures(synthetic_run, tmp_path_factory):
    """`at(width)`: {kind: [figure as drawn into its PNG]} of every kind (report_figures.KINDS) of
    the synthetic run at a journal width ("double", "single"), drawn once a session: the checks
    of test_report_print, test_report_force_names and test_report_single_width look at one drawing."""
    from orbitrig.analysis import plots

    drawn: dict[str, dict] = {}

    def at(width: str) -> dict:
        if width not in drawn:
            out = tmp_path_factory.mktemp(f"figures-{width}")
            drawn[width] = drawn_figures(synthetic_run, out, plots.COLUMN_WIDTHS[width], KINDS)
        return drawn[width]

    return at
