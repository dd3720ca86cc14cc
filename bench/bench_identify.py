"""Identification time: the paper's 33-coefficient model (kcd11 poly:2) over 20 orbit
frequencies, and identifiable models of similar size for comparison.

kcd11 poly:2 is ALWAYS rank-deficient (Omega^2 K_2 is an inertia term: Kxx_2 + Dxx, ...), so
`identify` ends in the refusal after the full analysis; the 33-column least-squares solve is
timed separately by each solver on the same matrix (its solution is not unique: time only).

Run: python3 bench/bench_identify.py   (prints one line per figure)
"""

from __future__ import annotations

import sys
import timeit
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from reduction.errors import IdentificationError  # noqa: E402
from reduction.identify import identify  # noqa: E402
from reduction.impedance import forces, impedance, regression  # noqa: E402
from reduction.models import model_spec  # noqa: E402
from reduction.regression import column_scale, lstsq  # noqa: E402
from reduction.table import OrbitTable  # noqa: E402

SPIN = 2 * np.pi * 1000 / 60
N_FREQ = 20


def table_for(model: str, freq_dep: str, seed: int = 0) -> OrbitTable:
    """20 orbit frequencies (0.2..1.2 x spin), forward and backward circular whirl at each
    (40 rows), forces from random coefficients of plausible size, 0.5 % force noise."""
    rng = np.random.default_rng(seed)
    spec = model_spec(model, freq_dep)
    size = {"K": 3e7, "C": 4e4, "D": 10.0}
    theta = np.array([size[t.matrix] * (1 + 0.3 * rng.standard_normal()) / 60.0**t.order for t in spec.terms])
    w = np.repeat(np.linspace(0.2, 1.2, N_FREQ) * SPIN, 2)
    r = 5e-6
    x = np.full(w.size, r, dtype=complex)
    y = np.tile([-1j * r, 1j * r], N_FREQ)
    fx, fy = forces(impedance(spec, theta, w), x, y)
    noise = 0.005 * np.sqrt(np.mean(np.abs(fx) ** 2))
    fx = fx + noise * (rng.standard_normal(w.size) + 1j * rng.standard_normal(w.size))
    fy = fy + noise * (rng.standard_normal(w.size) + 1j * rng.standard_normal(w.size))
    return OrbitTable(SPIN, w, x, y, fx, fy, np.full((w.size, 4), 0.999))


def best(fn, number: int) -> float:
    """Best of 5 repeats, seconds per call."""
    return min(timeit.repeat(fn, number=number, repeat=5)) / number


def refusal(table, model, freq_dep):
    try:
        identify(table, model, freq_dep)
    except IdentificationError:
        return
    raise AssertionError("expected a refusal")


def main() -> None:
    print(f"orbitrig identification benchmark: {N_FREQ} orbit frequencies x (forward + backward whirl) = "
          f"{2 * N_FREQ} rows, {8 * N_FREQ} real equations")
    t33 = table_for("kcd11", "poly:2")
    spec = model_spec("kcd11", "poly:2")
    print(f"kcd11 poly:2 ({spec.n_coefficients} coefficients): identify() incl. rank analysis and refusal: "
          f"{best(lambda: refusal(t33, 'kcd11', 'poly:2'), 20) * 1e3:.2f} ms")
    A, b = regression(spec, t33.orbit, t33.x, t33.y, t33.fx, t33.fy)
    A_s, _ = column_scale(A)
    print(f"kcd11 poly:2: build regression {A.shape[0]}x{A.shape[1]}: "
          f"{best(lambda: regression(spec, t33.orbit, t33.x, t33.y, t33.fx, t33.fy), 200) * 1e6:.0f} us")
    print("kcd11 poly:2: the 33-column matrix has rank 30: the solves below are timed only "
          "(their solution is not unique)")
    for solver in ("qr", "svd", "lu"):
        refused = []

        def solve(solver=solver):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                try:
                    lstsq(A_s, b, solver)
                except IdentificationError:
                    refused.append(True)  # lu: refinement cannot converge on a singular A^T A
        t = best(solve, 500)
        note = "  (ends in its refusal: singular normal equations)" if refused else ""
        print(f"kcd11 poly:2: 33-column least-squares solve, {solver}: {t * 1e6:.0f} us{note}")
    for model, fd in (("kc8", "poly:3"), ("kc8", "poly:4"), ("kcd12", "power:3")):
        table = table_for(model, fd)
        n = model_spec(model, fd).n_coefficients
        for method, solver in (("ols", "qr"), ("ols", "svd"), ("ols", "lu"), ("wls", "qr"), ("iv", "qr"), ("tls", "qr")):
            number = 5 if method == "tls" else 50
            t = best(lambda: identify(table, model, fd, method, solver), number)
            print(f"{model} {fd} ({n} coefficients, identifiable): identify {method}/{solver}: {t * 1e3:.2f} ms")


if __name__ == "__main__":
    main()
