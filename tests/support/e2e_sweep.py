"""Shared parts of the end-to-end tests: `orbitrig sweep --sim` at the paper's Table 1
operating point on a simulator scenario, and the identified impedance held against the
simulator's true Z(Omega) with its uncertainty (the fit's covariance and the systematic
budget of the rig's stated calibration uncertainty, as the sweep stores them)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from orbitrig.config import rig_from_text
from orbitrig.run.point_analysis import lms_calibration
from orbitrig.store.reader import read_run
from orbitrig.store.stored_run import Point
from reduction.identify import identify
from reduction.impedance import impedance_basis
from reduction.systematic import Calibration, uncertainty_budget

from .cli_helpers import orbitrig

#: the ten Omega/omega of the paper's Table 1
TABLE1_RATIOS = [0.247, 0.363, 0.471, 0.569, 0.677, 0.765, 0.871, 1.041, 1.139, 1.247]
SPEEDUP = 40.0  # the default of `sweep --sim`: the drives' watchdog holds under load
#: coverage factor of the per-frequency impedance check (the test's own, on u(Z); the sweep's U of a
#: coefficient takes its k per coefficient, docs/calibration.md)
K_COVERAGE = 2.0

MATRIX = """name = "table1"
description = "the paper's Table 1 operating point, its ten orbit frequencies"
revolutions = 50

[operating]
spin_rpm = [1000.0]
recess_pressure_mpa = [0.4826]
pressure_ratio = [0.25]
static_eccentricity = [0.0]
dynamic_eccentricity = [0.04]

[orbit]
ratios = {ratios}
directions = ["forward", "backward"]

[[models]]
model = "kcd11"

[[models]]
model = "kcd11"
freq_dep = "power:1"
"""


def sweep(tmp: Path, scenario: str | None) -> tuple[Path, str]:
    """Run `orbitrig sweep --sim` in a subprocess on `scenario` (a file under config/, None: the default rig);
    return the run directory and the terminal output."""
    matrix = tmp / "table1.toml"
    matrix.write_text(MATRIX.format(ratios=TABLE1_RATIOS))
    out = tmp / "run"
    args = ["sweep", "--sim", "--matrix", str(matrix), "--out", str(out), "--speedup", str(SPEEDUP)]
    if scenario is not None:
        args += ["--sim-config", scenario]
    p = orbitrig(*args, timeout=170, columns=None)
    assert p.returncode == 0, p.stdout + p.stderr
    return out, p.stdout


def the_point(out: Path) -> Point:
    run = read_run(out)
    assert run.status == "completed" and len(run.complete_points) == 1
    return run.complete_points[0]


def stated_calibration(out: Path, lms: str) -> Calibration:
    """The calibration uncertainty the run's rig configuration states ([calibration_uncertainty]),
    for the orbit table of `lms`, as the sweep's stored budget uses it."""
    rig = rig_from_text(read_run(out).rig_config, "stored rig config")
    assert rig.calibration_uncertainty is not None
    return lms_calibration(rig.calibration_uncertainty, lms)


def impedance_misfit(
    point: Point, lms: str, freq_dep: str, calibration: Calibration | None, stored_budget: bool = False
) -> np.ndarray:
    """Per orbit frequency: |Z_identified - Z_true| / (K_COVERAGE u(Z)), u(Z) the root of the
    summed variances of Z's eight real parts from the fit's covariance (+ the systematic
    budget of `calibration`; `stored_budget`: check it equals the one the sweep stored).
    Values <= 1: within the stated uncertainty."""
    table = point.tables[lms]
    ident = identify(table, model="kcd11", freq_dep=freq_dep)
    stored = point.identification(lms, "kcd11", freq_dep).result
    for key, value in stored["coefficients"].items():  # the stored fit is this one
        assert np.isclose(ident.coefficients[key], value, rtol=1e-9, atol=1e-9), key
    cov = ident.covariance
    if calibration is not None:
        budget = uncertainty_budget(ident, table, calibration)
        cov = budget.covariance_combined
        if stored_budget:  # `calibration` is the one the sweep used: its stored budget is this one
            for key, u in stored["uncertainty"]["combined"].items():
                assert np.isclose(budget.combined[key], u, rtol=1e-6), key
    truth = point.truth
    w = np.abs(np.asarray(truth["orbit"]))
    z_true = np.asarray(truth["Z_re"]) + 1j * np.asarray(truth["Z_im"])
    dz = ident.impedance(w) - z_true
    E = impedance_basis(ident.spec, w)  # (n, p, 2, 2): dZ / d theta
    var = np.einsum("kpij,pq,kqij->k", E.real, cov, E.real) + np.einsum("kpij,pq,kqij->k", E.imag, cov, E.imag)
    return np.linalg.norm(dz, axis=(1, 2)) / (K_COVERAGE * np.sqrt(var))
