"""Identification time: the paper's second-order polynomial model kcd11 poly:2 (fitted as 29
coefficients: K order 2 is absorbed by D) over 20 orbit frequencies, forward and backward
whirl at each (40 rows, 160 real equations), with the covariance, the 95 % intervals and the
systematic (type B, linearised) propagation of a full per-channel calibration budget.
Target: under 5 ms per point for identify + systematic propagation (no Monte Carlo).

Also: each method and solver on the same table, and a few other models for comparison.

Run: python3 -m bench.bench_identify   (prints one line per figure)
"""

from __future__ import annotations

import functools
import sys
import timeit

import numpy as np

from reduction.identify import identify
from reduction.impedance import forces, impedance, regression
from reduction.models import model_spec
from reduction.systematic import Calibration, ChannelCalibration, uncertainty_budget
from reduction.table import OrbitTable

SPIN = 2 * np.pi * 1000 / 60
N_FREQ = 20
CALIBRATION = Calibration(
    x=ChannelCalibration(gain=0.005, phase=np.radians(0.05), delay=1e-6),
    y=ChannelCalibration(gain=0.005, phase=np.radians(0.05), delay=1e-6),
    fx=ChannelCalibration(gain=0.01, phase=np.radians(0.3), delay=10e-6),
    fy=ChannelCalibration(gain=0.01, phase=np.radians(0.3), delay=10e-6),
    sensitivity=0.01,
)


def table_for(model: str, freq_dep: str, seed: int = 0) -> OrbitTable:
    """20 orbit frequencies (0.2..1.2 x spin), forward and backward circular whirl at each
    (40 rows), forces from random coefficients of plausible size, 0.5 % force noise, u_*
    columns stating it."""
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
    fx = fx + noise / np.sqrt(2) * (rng.standard_normal(w.size) + 1j * rng.standard_normal(w.size))
    fy = fy + noise / np.sqrt(2) * (rng.standard_normal(w.size) + 1j * rng.standard_normal(w.size))
    u = np.tile([1e-9, 1e-9, noise, noise], (w.size, 1))
    return OrbitTable(SPIN, w, x, y, fx, fy, np.full((w.size, 4), 0.999), np.full(w.size, 50), u)


def best(fn, number: int) -> float:
    """Best of 5 repeats, seconds per call."""
    return min(timeit.repeat(fn, number=number, repeat=5)) / number


def main() -> int:
    print(
        f"orbitrig identification benchmark: {N_FREQ} orbit frequencies x (forward + backward whirl) = "
        f"{2 * N_FREQ} rows, {8 * N_FREQ} real equations"
    )
    table = table_for("kcd11", "poly:2")
    spec = model_spec("kcd11", "poly:2")
    p = spec.n_coefficients
    print(f"kcd11 poly:2: {p} coefficients (the paper's 33 less the absorbed K order 2)")
    print(
        f"kcd11 poly:2: build regression (impedance basis reused): "
        f"{best(lambda: regression(spec, table.orbit, table.x, table.y, table.fx, table.fy), 200) * 1e6:.0f} us"
    )
    ident = identify(table, "kcd11", "poly:2")
    t_id = best(lambda: identify(table, "kcd11", "poly:2"), 50)
    t_sys = best(lambda: uncertainty_budget(ident, table, CALIBRATION), 50)
    t_all = best(lambda: uncertainty_budget(identify(table, "kcd11", "poly:2"), table, CALIBRATION), 50)
    print(
        f"kcd11 poly:2 ols/qr: identify (rank analysis, covariance, intervals, chi2, AIC/BIC, "
        f"conditioning check): {t_id * 1e3:.2f} ms"
    )
    print(
        f"kcd11 poly:2: systematic propagation (14 calibration parameters, linearised) + budget: {t_sys * 1e3:.2f} ms"
    )
    print(
        f"kcd11 poly:2: identify + covariance + systematic propagation: {t_all * 1e3:.2f} ms "
        f"(target < 5 ms) -> {'met' if t_all < 5e-3 else 'NOT met'}"
    )
    status = 0 if t_all < 5e-3 else 1
    for method, solver in (("ols", "svd"), ("ols", "lu"), ("wls", "qr"), ("iv", "qr"), ("tls", "qr")):
        number = 5 if method == "tls" else 50
        t = best(functools.partial(identify, table, "kcd11", "poly:2", method, solver), number)
        print(f"kcd11 poly:2 ({p} coefficients): identify {method}/{solver}: {t * 1e3:.2f} ms")
    for model, fd in (("kc8", "poly:3"), ("kcd12", "power:3"), ("kcd12", "poly:2")):
        t_other = table_for(model, fd)
        n = model_spec(model, fd).n_coefficients
        t = best(functools.partial(identify, t_other, model, fd), 50)
        print(f"{model} {fd} ({n} coefficients): identify ols/qr: {t * 1e3:.2f} ms")
    return status


if __name__ == "__main__":
    sys.exit(main())
