"""`orbitrig sweep --help` and the README say where the closing table's numbers are in full:
run.h5 (orbitrig.open_run) and an export's fits.csv, not coefficients.csv, which rounds them
for reading (8 significant digits for the coefficients, 6 for std and U: docs/storage.md)."""

from __future__ import annotations

from typer.testing import CliRunner

from orbitrig.cli import app
from support.paths import ROOT


def _help_words() -> str:
    out = CliRunner().invoke(app, ["sweep", "--help"], env={"COLUMNS": "300"}).stdout
    return " ".join(out.replace("│", " ").split())


def test_sweep_help_points_to_the_files_that_keep_every_number():
    words = _help_words()
    assert "every number in full, SI: DIR/run.h5 (orbitrig.open_run; `orbitrig export` fits.csv)" in words
    assert "every number in full, SI: DIR/coefficients.csv" not in words


def test_readme_says_coefficients_csv_rounds():
    readme = " ".join((ROOT / "README.md").read_text().split())
    assert "(every number in full: the run's `coefficients.csv`)" not in readme
    assert "`coefficients.csv` rounds to 8 and 6 significant digits" in readme
