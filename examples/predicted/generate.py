"""Regenerate sim-bearing.csv: the simulator's own bearing as a model's prediction.

    PYTHONPATH=. python3 examples/predicted/generate.py   (from the repository root)

What `orbitrig compare --predicted` reads (docs/catalog.md): one line per condition, here
config/matrices/eccentricity.toml's operating point at static eccentricity 0 to 0.3 in steps
of 0.05. Each line holds the constant K, C, D best fitting the default simulator's true
impedance Z(Omega) over the matrix's orbit ratios (sim.fits.constant_fit, as a --sim run
stores it in truth/fits/constant), so the measured points of a --sim run of that matrix
should scatter about it within their U. A bulk-flow or CFD code's output takes its place
on the rig.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from orbitrig.config import load_matrix, shipped_config
from rigunits import MPA, RPM, coefficient_unit
from sim.config import SimConfig
from sim.fits import constant_fit
from sim.physics import RigPhysics

HERE = Path(__file__).resolve().parent
ECCENTRICITIES = np.round(np.arange(0.0, 0.301, 0.05), 2)
NAMES = [f"{m}{i}{j}" for m in "KCD" for i in "xy" for j in "xy"]


def main() -> None:
    matrix = load_matrix(shipped_config() / "matrices" / "eccentricity.toml")
    op = matrix.operating
    (spin_rpm,), (recess_mpa,), (beta,), (eps_d,) = (
        op.spin_rpm,
        op.recess_pressure_mpa,
        op.pressure_ratio,
        op.dynamic_eccentricity,
    )
    spin = spin_rpm * RPM
    orbits = np.asarray(matrix.orbit.ratios) * spin
    physics = RigPhysics(SimConfig())
    rows = []
    for eps_s in ECCENTRICITIES:
        physics.set_manual(static_eccentricity=eps_s, recess_pressure=recess_mpa * MPA, pressure_ratio=beta)
        fit = constant_fit(orbits, physics.impedances(spin, orbits))
        values = [fit[n[0]][("xy".index(n[1]), "xy".index(n[2]))] for n in NAMES]
        rows.append([spin_rpm, recess_mpa, beta, eps_s, eps_d, *(f"{v:.6g}" for v in values)])
    path = HERE / "sim-bearing.csv"
    with path.open("w", newline="") as f:
        f.write("# the default simulator's bearing (examples/predicted/generate.py): constant K, C, D best\n")
        f.write(f"# fitting its true Z(Omega) at Omega/omega = {', '.join(f'{r:g}' for r in matrix.orbit.ratios)}\n")
        out = csv.writer(f, lineterminator="\n")
        header = ["spin_rpm", "recess_pressure_mpa", "pressure_ratio", "static_eccentricity", "dynamic_eccentricity"]
        out.writerow(header + [f"{n} [{coefficient_unit(n)}]" for n in NAMES])
        out.writerows(rows)
    print(path, f"{len(rows)} lines")


if __name__ == "__main__":
    main()
