"""Write a small run directory per docs/storage.md from synthetic data of known
coefficients (no rig, no simulator): the fast stand-in for a real sweep."""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np

from reduction.errors import IdentificationError
from reduction.identify import identify
from reduction.table import OrbitTable

SPIN_RPM = 1000.0
SPIN = SPIN_RPM * np.pi / 30.0
RATIOS = np.linspace(0.2, 1.2, 10)
R = 0.04 * 60e-6  # dynamic eccentricity 0.04 of a 60 um clearance
# hydrostatic-bearing-like true coefficients (SI): D symmetric so kcd11 fits exactly
K_TRUE = np.array([[3.3e7, 4.0e6], [-3.5e6, 3.1e7]])
C_TRUE = np.array([[5.2e4, 1.5e3], [1.5e3, 4.9e4]])
D_TRUE = np.array([[18.0, 2.0], [2.0, 21.0]])
STRAIN_GAIN = 1.018 * np.exp(1j * np.radians(0.3))  # LMS 2 reads 1.8 % / 0.3 deg off (paper Fig. 4a)
MODELS = (("kcd11", "none"), ("kc7", "none"), ("kcd11", "power:1"), ("kcd12", "poly:2"))


def forces(orbit, x, y):
    z = K_TRUE[None] + 1j * orbit[:, None, None] * C_TRUE[None] - orbit[:, None, None] ** 2 * D_TRUE[None]
    d = np.stack([x, y], axis=-1)
    f = -np.einsum("nij,nj->ni", z, d)
    return f[:, 0], f[:, 1]


def make_table(rng, noise):
    omega = np.concatenate([RATIOS, RATIOS]) * SPIN
    direction = np.concatenate([np.ones(10), -np.ones(10)])
    x = np.full(20, R, complex) * (1 + 0.01 * rng.standard_normal(20))
    y = -1j * direction * R * (1 + 0.01 * rng.standard_normal(20))
    fx, fy = forces(omega, x, y)
    scale = noise * np.abs(fx).mean()
    fx = fx + scale * (rng.standard_normal(20) + 1j * rng.standard_normal(20))
    fy = fy + scale * (rng.standard_normal(20) + 1j * rng.standard_normal(20))
    gamma2 = np.clip(0.995 - 0.04 * rng.random((20, 4)), 0, 1)
    return OrbitTable(spin=SPIN, orbit=omega, x=x, y=y, fx=fx, fy=fy, gamma2=gamma2), direction


def write_synthetic_run(directory: Path, *, noise=1e-3, seed=1, n_points=2, incomplete=1) -> Path:
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    with h5py.File(directory / "run.h5", "w") as h5:
        h5.attrs.update(
            format="orbitrig-run/1", software_version="0.1.0", created="2026-01-01T00:00:00Z",
            status="stopped" if incomplete else "completed", status_message="synthetic",
            sim=True, rig_config="[adc]\n", matrix_config="name = 'synthetic'\n", matrix_name="synthetic",
        )
        for p in range(n_points + incomplete):
            g = h5.create_group(f"points/{p:04d}")
            eps_s = 0.15 * p
            g.attrs.update(
                index=p, spin=SPIN, spin_rpm=SPIN_RPM, recess_pressure=0.4826e6, pressure_ratio=0.25,
                static_eccentricity=eps_s, dynamic_eccentricity=0.04, orbit_radius=R,
                label=f"1000 rpm, eps_s {eps_s:g}",
            )
            tables = {}
            piezo, direction = make_table(rng, noise)
            tables["piezo"] = piezo
            tables["strain"] = OrbitTable(SPIN, piezo.orbit, piezo.x, piezo.y, piezo.fx * STRAIN_GAIN,
                                          piezo.fy * STRAIN_GAIN, piezo.gamma2)
            for i, (w, dr) in enumerate(zip(piezo.orbit, direction)):
                fg = g.create_group(f"frequencies/{i % 10:02d}_{'fwd' if dr > 0 else 'bwd'}")
                fg.attrs.update(orbit=w * dr, orbit_hz=w / 2 / np.pi, direction=int(dr),
                                measured_orbit_speed=w * dr, complete=True)
                fg["coherence"] = np.stack([tables["piezo"].gamma2[i], tables["strain"].gamma2[i]])
            if p >= n_points:  # an incomplete point: frequencies written, never marked complete
                continue
            for lms, t in tables.items():
                tg = g.create_group(f"table/{lms}")
                tg.attrs["spin"] = t.spin
                for name in ("orbit", "x", "y", "fx", "fy", "gamma2"):
                    tg[name] = getattr(t, name)
                for model, fd in MODELS:
                    ig = g.create_group(f"identification/{lms}__{model}__{fd.replace(':', '_').replace(',', '_')}")
                    try:
                        ig.attrs["json"] = json.dumps(identify(t, model=model, freq_dep=fd).to_dict())
                    except IdentificationError as err:
                        ig.attrs["error"] = str(err)
            hz = (piezo.orbit / 2 / np.pi).tolist()
            g.create_group("truth").attrs["json"] = json.dumps({
                "orbit_hz": hz, "K": [K_TRUE.tolist()] * 20, "C": [C_TRUE.tolist()] * 20,
                "D": [D_TRUE.tolist()] * 20, "K0": K_TRUE.tolist(), "C0": C_TRUE.tolist(), "D0": D_TRUE.tolist(),
            })
            ratio = tables["strain"].fx / tables["piezo"].fx
            g.create_group("lms_comparison").attrs["json"] = json.dumps({
                "orbit_hz": hz, "fx_amp_ratio": np.abs(ratio).tolist(),
                "fx_phase_diff_deg": np.degrees(np.angle(ratio)).tolist(),
            })
            g.attrs["complete"] = True
    return directory
