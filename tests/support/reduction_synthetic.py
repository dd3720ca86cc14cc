"""Synthetic orbit tables from known coefficients, computed directly from the spec's
formula f = -Z d, Z = sum_r Omega^r (K_r + i Omega C_r - Omega^2 D_r) - independent of the
regression code under test."""

from __future__ import annotations

import numpy as np

from reduction.table import OrbitTable

SPIN = 2 * np.pi * 1000 / 60  # 1000 rpm in rad/s

K0 = np.array([[3.3e7, 1.1e7], [-0.9e7, 2.9e7]])
C0 = np.array([[4.0e4, 0.6e4], [0.8e4, 3.6e4]])
D0 = np.array([[12.0, 1.5], [2.5, 10.0]])


def truth(model: str, orders: dict[str, tuple[int, ...]], seed: int = 1) -> dict[tuple[str, int], np.ndarray]:
    """Known matrices {(matrix, order): 2x2} with the model's symmetry; the order-r term is
    scaled so that it contributes ~20 % of the constant term at Omega = 60 rad/s."""
    rng = np.random.default_rng(seed)
    base = {"K": K0, "C": C0, "D": D0}
    mats = {"kc7": "KC", "kc8": "KC", "kcd11": "KCD", "kcd12": "KCD"}[model]
    out = {}
    for m in mats:
        for r in orders[m]:
            M = base[m] * (1.0 if r == 0 else 0.2 * (1 + 0.3 * rng.standard_normal((2, 2))) / 60.0**r)
            if (m == "C" and model == "kc7") or (m == "D" and model == "kcd11"):
                M = (M + M.T) / 2
            out[(m, r)] = M
    return out


def keys_of(true: dict) -> dict[str, float]:
    out = {}
    for (m, r), M in true.items():
        for i, a in enumerate("xy"):
            for j, b in enumerate("xy"):
                out[f"{m}{a}{b}" + (f"_{r}" if r else "")] = float(M[i, j])
    return out


def impedance(true: dict, w: np.ndarray) -> np.ndarray:
    w = np.asarray(w, dtype=float)[:, None, None]
    Z = np.zeros((w.shape[0], 2, 2), dtype=complex)
    factor = {"K": 1.0, "C": 1j * w, "D": -(w**2)}
    for (m, r), M in true.items():
        Z = Z + w**r * factor[m] * M
    return Z


def orbit_table(
    true: dict, orbit_hz, shapes=("forward", "backward"), radius: float = 5e-6, gamma2=None, phase: float = 0.3
) -> OrbitTable:
    """One row per (frequency, shape); shapes: forward | backward | ellipse (a, b, tilt)."""
    w, x, y = [], [], []
    for f in orbit_hz:
        for s in shapes:
            w.append(2 * np.pi * f)
            if s == "forward":
                x.append(radius * np.exp(1j * phase)), y.append(-1j * radius * np.exp(1j * phase))
            elif s == "backward":
                x.append(radius * np.exp(1j * phase)), y.append(1j * radius * np.exp(1j * phase))
            else:
                a, b, tilt = s
                # ellipse: semi-axes a, b (m), rotated by tilt: x + i y traced as a cos t + i b sin t
                xr, yr = a, -1j * b
                c, sn = np.cos(tilt), np.sin(tilt)
                x.append(c * xr - sn * yr), y.append(sn * xr + c * yr)
    w, x, y = np.array(w), np.array(x), np.array(y)
    Z = impedance(true, w)
    fx = -(Z[:, 0, 0] * x + Z[:, 0, 1] * y)
    fy = -(Z[:, 1, 0] * x + Z[:, 1, 1] * y)
    g = None if gamma2 is None else np.broadcast_to(np.asarray(gamma2, dtype=float), (w.size, 4)).copy()
    return OrbitTable(SPIN, w, x, y, fx, fy, g)


def frequencies(n: int, lo: float = 0.2, hi: float = 1.2) -> np.ndarray:
    """n orbit frequencies (Hz) from lo to hi times the spin speed (the paper's range)."""
    return np.linspace(lo, hi, n) * SPIN / (2 * np.pi)


def cnoise(rng: np.random.Generator, std, shape) -> np.ndarray:
    """Complex circular noise with E|n|^2 = std^2 (std broadcast to shape)."""
    return np.asarray(std) / np.sqrt(2) * (rng.standard_normal(shape) + 1j * rng.standard_normal(shape))


def with_force_noise(clean: OrbitTable, rng: np.random.Generator, std: float) -> OrbitTable:
    """``clean`` with complex noise of standard deviation ``std`` (N) on fx and fy, nothing else."""
    n = clean.n
    return OrbitTable(
        clean.spin, clean.orbit, clean.x, clean.y, clean.fx + cnoise(rng, std, n), clean.fy + cnoise(rng, std, n)
    )


def with_noise(clean: OrbitTable, rng: np.random.Generator, u, stated: bool = True) -> OrbitTable:
    """``clean`` with complex noise on x, y, fx and fy (drawn in that order) of standard deviations
    ``u`` = (u_x, u_y, u_fx, u_fy) (m, m, N, N; each a number or one per row); ``stated``: the
    table carries them as its u_* columns."""
    n = clean.n
    sd = np.stack([np.broadcast_to(np.asarray(v, dtype=float), (n,)) for v in u], axis=1)
    x, y = clean.x + cnoise(rng, sd[:, 0], n), clean.y + cnoise(rng, sd[:, 1], n)
    fx, fy = clean.fx + cnoise(rng, sd[:, 2], n), clean.fy + cnoise(rng, sd[:, 3], n)
    return OrbitTable(clean.spin, clean.orbit, x, y, fx, fy, u=sd if stated else None)


def coherent_noise_tables(
    true: dict, rng: np.random.Generator, count: int, gamma_one_row: int | None = None
) -> list[OrbitTable]:
    """``count`` tables of ``true`` at 6 frequencies whose force noise follows their coherences
    (50 records per row, per-record relative noise 0.15 .. 1.5, gamma^2 = 1 / (1 + rel^2));
    optionally one row reads gamma^2 = 1.000."""
    clean = orbit_table(true, frequencies(6))
    n_rec = 50
    rel = np.geomspace(0.15, 1.5, clean.n)  # relative force noise of one record, per row
    g = np.repeat((1 / (1 + rel**2))[:, None], 4, axis=1)  # coherent power over total power
    if gamma_one_row is not None:
        g[gamma_one_row] = 1.0
    avg = rel / np.sqrt(n_rec)  # relative noise of the average of n_rec records
    return [
        OrbitTable(
            clean.spin,
            clean.orbit,
            clean.x,
            clean.y,
            clean.fx + cnoise(rng, avg * np.abs(clean.fx), clean.n),
            clean.fy + cnoise(rng, avg * np.abs(clean.fy), clean.n),
            g,
            np.full(clean.n, n_rec),
        )
        for _ in range(count)
    ]
