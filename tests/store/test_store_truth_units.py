"""The simulator's power-fit truth in run.h5 keeps each term's unit with its own exponent
(Eq. 15: K = K0 + |Omega|^m Km, ...): the file's annotation, which gives every dataset its
unit, must not put back the exponent 1 over a fit with m = 2."""

from __future__ import annotations

import h5py
import numpy as np

from orbitrig.store.annotate import annotate
from orbitrig.store.pieces import write_truth


def _truth(exponents: list[int]) -> dict:
    eye = np.eye(2).tolist()
    return {
        "definition": "test truth",
        "orbit": [10.0, -10.0],
        "orbit_hz": [1.59, -1.59],
        "Z_re": np.ones((2, 2, 2)).tolist(),
        "Z_im": np.zeros((2, 2, 2)).tolist(),
        "band": [10.0, 10.0],
        "fits": {
            "constant": {"K": eye, "C": eye, "D": eye},
            "power": {"exponents": exponents, **{k: eye for k in ("K0", "Km", "C0", "Cn", "D0", "Dp")}},
        },
    }


def test_power_fit_units_carry_their_exponents_after_annotation(tmp_path):
    with h5py.File(tmp_path / "t.h5", "w") as f:
        point = f.create_group("point_0000")
        write_truth(point.create_group("truth"), _truth([2, 3, 1]))
        annotate(point)
    with h5py.File(tmp_path / "t.h5", "r") as f:
        power = f["point_0000/truth/fits/power"]
        units = {k: power[k].attrs["units"] for k in ("K0", "Km", "C0", "Cn", "D0", "Dp")}
    assert units == {
        "K0": "N/m",
        "Km": "N/m (rad/s)^-2",
        "C0": "N s/m",
        "Cn": "N s/m (rad/s)^-3",
        "D0": "kg",
        "Dp": "kg (rad/s)^-1",
    }
