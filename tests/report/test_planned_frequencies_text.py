"""Planned orbit frequencies reach the files as the matrix meant them: the synthetic run's
ratios 0.2 .. 1.2 at 1000 rpm are 10/3, 5, ..., 20 Hz, and 0.3 x 1000 rpm written as
0.3 x 1000 x 2 pi / 60 rad/s over 2 pi is 4.999999999999999, which no CSV may show."""

from __future__ import annotations

import csv
import io
import json
import math

import numpy as np
from typer.testing import CliRunner

from orbitrig.cli import app
from rigunits import RPM, in_hz, in_rpm, without_noise

#: the synthetic run's ratios (support.report_synthetic) and the frequencies meant, Hz
RATIOS = (0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.1, 1.2)
MEANT = [r * 1000 / 60 for r in RATIOS]
#: the whole ones as a file must spell them (each once per whirl direction in an orbit table)
WHOLE = {0.3: "5.0", 0.6: "10.0", 0.9: "15.0", 1.2: "20.0"}


def _column(text: str, name: str) -> list[str]:
    rows = list(csv.reader(io.StringIO(text)))
    k = rows[0].index(name)
    return [r[k] for r in rows[1:] if r]


def _planned(cells: list[str], per_ratio: int) -> None:
    """`cells` (per_ratio per ratio, ascending) spell the whole frequencies exactly and the
    others (10/3 Hz ...) as doubles within 1e-15 of the meant value."""
    assert len(cells) == per_ratio * len(RATIOS)
    for k, r in enumerate(RATIOS):
        for cell in cells[per_ratio * k : per_ratio * (k + 1)]:
            assert cell == WHOLE.get(r, cell) and math.isclose(float(cell), MEANT[k], rel_tol=1e-15)
    assert not any("9999999" in c or "0000001" in c for c in cells)


def test_edge_speeds_carry_no_float_noise() -> None:
    spin = 1000 * RPM  # rad/s, as the plan has it; a block's orbit is ratio x spin
    assert 0.3 * spin / (2 * math.pi) == 4.999999999999999  # the noise the edge removes
    assert in_hz(0.3 * spin) == 5.0 and in_hz(1.2 * spin) == 20.0
    assert in_hz(0.2 * spin) == 0.2 * spin / (2 * math.pi)  # 10/3 has no short decimal: kept
    assert 20.5 * RPM / RPM == 20.499999999999996 and in_rpm(20.5 * RPM) == 20.5
    rng = np.random.default_rng(3)
    measured = rng.uniform(0.1, 500.0, 100_000)
    moved = np.abs(without_noise(measured) - measured) / measured
    assert moved.max() <= 8.9e-16 and np.count_nonzero(moved) < 300  # 4 ulps at most, rarely
    hz = without_noise(np.array([4.999999999999999, -19.999999999999996, 0.0, np.nan, np.inf, 1e-320]))
    assert hz[:3].tolist() == [5.0, -20.0, 0.0] and np.isnan(hz[3]) and hz[4] == np.inf and hz[5] == 1e-320


def test_exported_tables_and_derived_quantities_read_the_planned_hz(synthetic_run, tmp_path) -> None:
    out = tmp_path / "export"
    assert CliRunner().invoke(app, ["export", str(synthetic_run), "--out", str(out)]).exit_code == 0
    table = (out / "point_0000_piezo.csv").read_text(encoding="utf-8")
    _planned(_column(table, "orbit_hz [Hz]"), 2)  # both whirl directions
    assert set(_column(table, "spin_rpm [rpm]")) == {"1000.0"}
    derived = (out / "derived_0000_piezo__kcd11__none__ols.csv").read_text(encoding="utf-8")
    _planned(_column(derived, "orbit_hz [Hz]"), 1)


def test_identify_and_reduce_report_the_planned_hz(synthetic_run, tmp_path) -> None:
    out = tmp_path / "export"
    CliRunner().invoke(app, ["export", str(synthetic_run), "--out", str(out), "--point", "0"])
    table = str(out / "point_0000_piezo.csv")
    text = CliRunner().invoke(app, ["identify", table, "--model", "kcd11", "--format", "csv"]).stdout
    forces = text.split("# Reproduced vs measured force")[1].split("\n\n")[0].split("\n", 1)[1]
    _planned(_column(forces, "orbit_hz [Hz]"), 2)
    reduced = json.loads(CliRunner().invoke(app, ["reduce", str(synthetic_run), "--model", "kcd11", "--json"]).stdout)
    _planned([repr(r["orbit_hz"]) for r in reduced["results"][0]["fit"]], 2)
