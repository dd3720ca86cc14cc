"""`identify`'s text summary tells a chi2 as its warning does (reduction.statistics.chi2_tail):
a chi2 far below its degrees of freedom by its lower tail, not as "p = 1"."""

from __future__ import annotations

import dataclasses
import re

import numpy as np
from scipy import stats
from typer.testing import CliRunner

from orbitrig.cli import app
from orbitrig.store.orbit_table import write_orbit_table
from support.reduction_synthetic import frequencies, orbit_table, truth, with_force_noise

NOISE = 0.01  # N, the forces' real noise
STATED = 1.0  # N, the u_fx, u_fy the table states: 100 x overstated


def _summary(tmp_path, stated: float) -> tuple[str, str]:
    clean = orbit_table(truth("kc8", {"K": (0,), "C": (0,)}), frequencies(8))
    noisy = with_force_noise(clean, np.random.default_rng(3), NOISE)
    u = np.tile([1e-12, 1e-12, stated, stated], (noisy.n, 1))
    path = tmp_path / "t.csv"
    write_orbit_table(path, dataclasses.replace(noisy, u=u))
    res = CliRunner().invoke(app, ["identify", str(path), "--model", "kc8"])
    assert res.exit_code == 0, res.output
    (line,) = [ln for ln in res.stdout.splitlines() if ln.startswith("chi2 ")]
    return line, res.stderr


def test_an_overstated_u_gives_the_lower_tail_in_summary_and_warning(tmp_path) -> None:
    line, stderr = _summary(tmp_path, STATED)
    chi2, dof = float(line.split()[1]), 4 * 16 - 8
    assert chi2 < 0.1 * dof  # about dof x (NOISE / STATED)^2
    said = re.search(r"\(lower-tail p = ([0-9.e+-]+)\)", line)
    assert said is not None and "(p = 1)" not in line, line
    assert abs(float(said[1]) / stats.chi2.cdf(chi2, dof) - 1) < 0.05
    assert f"degrees of freedom ({said[0][1:-1]})" in stderr  # the warning's very words


def test_a_stated_u_that_fits_keeps_the_upper_tail(tmp_path) -> None:
    line, stderr = _summary(tmp_path, NOISE)
    p = float(re.search(r"\(p = ([0-9.e+-]+)\)", line)[1])
    assert 1e-3 < p < 1 - 1e-3 and "lower-tail" not in line and "warning: chi2" not in stderr
