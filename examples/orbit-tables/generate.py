"""Regenerate the example orbit tables and truth.json (deterministic: fixed seeds).

    PYTHONPATH=. python3 examples/orbit-tables/generate.py   (from the repository root)

Each table is computed from known coefficients with f = -Z(Omega) d,
Z = sum_r Omega^r (K_r + i Omega C_r - Omega^2 D_r), plus complex noise of the stated
standard uncertainty on every phasor (written into the u_* columns, 50 records per row).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from orbitrig.store.orbit_table import write_orbit_table
from reduction.table import OrbitTable

HERE = Path(__file__).resolve().parent
SPIN_RPM = 3000.0
RADIUS = 10e-6  # m
K0 = [[3.3e7, 1.1e7], [-0.9e7, 2.9e7]]
C0 = [[4.0e4, 0.6e4], [0.6e4, 3.6e4]]
D0 = [[12.0, 1.5], [1.5, 10.0]]


def _orbits(hz, shapes):
    w, x, y = [], [], []
    for f in hz:
        for shape in shapes:
            a, b = shape  # complex forward / backward whirl components
            w.append(2 * math.pi * f)
            x.append(a + b)
            y.append(-1j * a + 1j * b)
    return np.array(w), np.array(x), np.array(y)


def _table(matrices, hz, shapes, u_d, u_f_rel, seed, with_u=True, gamma2=False):
    rng = np.random.default_rng(seed)
    w, x, y = _orbits(hz, shapes)
    Z = np.zeros((w.size, 2, 2), dtype=complex)
    for (m, r), M in matrices.items():
        factor = {"K": 1.0, "C": 1j * w, "D": -(w**2)}[m]
        Z += (w**r * factor)[:, None, None] * np.asarray(M)
    fx, fy = -(Z[:, 0, 0] * x + Z[:, 0, 1] * y), -(Z[:, 1, 0] * x + Z[:, 1, 1] * y)
    u_f = u_f_rel * float(np.sqrt(np.mean(np.abs(fx) ** 2 + np.abs(fy) ** 2) / 2))

    def noise(s):
        return s / math.sqrt(2) * (rng.standard_normal(w.size) + 1j * rng.standard_normal(w.size))

    u = np.tile([u_d, u_d, u_f, u_f], (w.size, 1))
    g = None
    if gamma2:  # coherences of 50 records with the same per-record noise
        rel = np.sqrt(50) * u_f / np.maximum(np.abs(np.stack([fx, fx, fy, fy], 1)), 1e-30)
        g = 1 / (1 + rel**2)
    return OrbitTable(
        2 * math.pi * SPIN_RPM / 60,
        w,
        x + noise(u_d),
        y + noise(u_d),
        fx + noise(u_f),
        fy + noise(u_f),
        g,
        np.full(w.size, 50) if with_u else None,
        u if with_u else None,
    )


def _keys(matrices):
    out = {}
    for (m, r), M in matrices.items():
        for i, a in enumerate("xy"):
            for j, b in enumerate("xy"):
                out[f"{m}{a}{b}" + (f"_{r}" if r else "")] = float(np.asarray(M)[i, j])
    return out


def main() -> None:
    hz = np.linspace(10.0, 60.0, 10)
    both = [(RADIUS, 0.0), (0.0, RADIUS)]  # forward and backward circles
    w_ref = 2 * math.pi * 35.0
    poly = {
        ("K", 0): K0,
        ("K", 1): (np.array(K0) * 0.1 / w_ref).tolist(),
        ("C", 0): C0,
        ("C", 1): (np.array(C0) * 0.1 / w_ref).tolist(),
        ("C", 2): (np.array(C0) * 0.05 / w_ref**2).tolist(),
        ("D", 0): D0,
        ("D", 1): (np.array(D0) * 0.1 / w_ref).tolist(),
        ("D", 2): (np.array(D0) * 0.05 / w_ref**2).tolist(),
    }
    const = {("K", 0): K0, ("C", 0): C0, ("D", 0): D0}
    ellipse = [(RADIUS * 0.99, RADIUS * 0.01)]  # forward, 2 % ellipticity, one fixed shape
    examples = {
        "kcd11-constant.csv": (
            const,
            hz,
            both,
            1e-8,
            2e-3,
            1,
            True,
            False,
            "--model kcd11 --method wls",
            "constant K, C, D (D symmetric); u_* columns",
        ),
        "kcd11-poly2.csv": (
            poly,
            np.linspace(10.0, 60.0, 12),
            both,
            1e-9,
            2e-4,
            2,
            True,
            False,
            "--model kcd11 --freq-dep poly:2",
            "the paper's 33-coefficient model: fitted as 29 (K order 2 absorbed by D)",
        ),
        "kc8-coherence.csv": (
            {("K", 0): K0, ("C", 0): C0},
            hz,
            both,
            0.0,
            1e-3,
            3,
            False,
            True,
            "--model kc8 --method wls",
            "coherences only (no u_*): wls falls back on them",
        ),
        "forward-ellipse.csv": (
            {
                ("K", 0): K0,
                ("C", 0): C0,
                ("K", 1): (np.array(K0) * 0.1 / w_ref).tolist(),
                ("C", 1): (np.array(C0) * 0.1 / w_ref).tolist(),
            },
            hz,
            ellipse,
            1e-9,
            1e-3,
            4,
            True,
            False,
            "--model kc8 --freq-dep power:1",
            "forward whirl only, one fixed 2 % ellipse: power:1 is refused (exit 2)",
        ),
    }
    truth = {}
    for name, (mats, f, shapes, u_d, u_f, seed, with_u, gamma2, args, what) in examples.items():
        write_orbit_table(HERE / name, _table(mats, f, shapes, u_d, u_f, seed, with_u, gamma2))
        truth[name] = {"command": args, "description": what, "spin_rpm": SPIN_RPM, "coefficients": _keys(mats)}
    truth["forward-ellipse.csv"]["exit_status"] = 2
    (HERE / "truth.json").write_text(json.dumps(truth, indent=2) + "\n")


if __name__ == "__main__":
    main()
