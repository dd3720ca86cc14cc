"""A simulated rig's truth at one operating point, and how far an identification is from it.

The truth is what the simulator's bearing is: its impedance Z(Omega) (2x2 complex, N/m)
at each orbit frequency of the point, f_bar = -Z d_bar. It is not a set of coefficients
of the model being identified: a real bearing's Z need not have the form
K + i Omega C - Omega^2 D. For reference the point's truth also holds the best fits of
that Z over the point's own orbit speeds (the `band`): constant coefficients K, C, D and
the paper's Eq. 15 power form. ``K0``, ``C0``, ``D0`` repeat the constant best fit
(what the coefficients.csv ``true_*`` columns show).

Rows follow the orbit table: blocks sorted by frequency, forward before backward; the
orbit speed of a row is the measured one (as in the table), signed by the direction.
Pure (no I/O).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from orbitrig.run.corrections import block_orbit_speed
from orbitrig.run.plan import OperatingPoint
from orbitrig.run.rig_io import TruthSource
from orbitrig.store.records import BlockRecord
from reduction.impedance import impedance
from reduction.models import model_spec, resolved_freq_dep

#: the truth's definition, stored with it
DEFINITION = (
    "Z: the simulator's true impedance at each row's |Omega| (one Z for both whirl directions), "
    "f_bar = -Z d_bar (N/m); "
    "fits: best fits of Z over band (the point's |Omega|), constant K, C, D and Eq. 15 power form; "
    "K0, C0, D0 = fits.constant"
)


def row_orbit(rec: BlockRecord) -> float:
    """Signed orbit speed of a block (rad/s): the measured |Omega| when there is one, as the table."""
    return math.copysign(block_orbit_speed(rec), rec.block.direction)


def point_truth(p: OperatingPoint, recs: list[BlockRecord], source: TruthSource) -> dict[str, Any]:
    """The truth of point `p` as stored (JSON-ready): orbit, orbit_hz, Z_re, Z_im per row,
    band, fits {"constant", "power"}, K0 C0 D0."""
    recs = sorted(recs, key=lambda r: (r.block.freq, -r.block.direction))
    orbit = np.array([row_orbit(r) for r in recs])
    z = np.asarray(source.impedance(p.spin, orbit), dtype=complex)
    band = np.unique(np.abs(orbit))
    fits = source.reference_fits(p.spin, band)
    const = {k: np.asarray(v, dtype=float).tolist() for k, v in fits["constant"].items()}
    power = {
        k: (list(v) if k == "exponents" else np.asarray(v, dtype=float).tolist()) for k, v in fits["power"].items()
    }
    return {
        "definition": DEFINITION,
        "orbit": orbit.tolist(),
        "orbit_hz": [r.block.orbit_hz for r in recs],
        "Z_re": z.real.tolist(),
        "Z_im": z.imag.tolist(),
        "band": band.tolist(),
        "fits": {"constant": const, "power": power},
        "K0": const["K"],
        "C0": const["C"],
        "D0": const["D"],
    }


def true_impedance(truth: dict[str, Any]) -> np.ndarray:
    """The stored true Z (n, 2, 2) complex of a point's truth."""
    z: np.ndarray = np.asarray(truth["Z_re"], dtype=float) + 1j * np.asarray(truth["Z_im"], dtype=float)
    return z


def stored_impedance(result: dict[str, Any], orbits: ArrayLike) -> np.ndarray:
    """Z(Omega) (n, 2, 2) of a stored identification (its JSON object) at `orbits` rad/s."""
    spec = model_spec(result["model"], resolved_freq_dep(result["freq_dep"], result.get("exponent")))
    values = [result["coefficients"].get(k) for k in spec.names]
    theta = np.array([math.nan if v is None else float(v) for v in values])
    return impedance(spec, theta, np.abs(np.asarray(orbits, dtype=float)))


def impedance_deviation(result: dict[str, Any], truth: dict[str, Any]) -> np.ndarray:
    """|Z_identified - Z_true| / |Z_true| (Frobenius norms) at each truth row (n,)."""
    z_true = true_impedance(truth)
    z_id = stored_impedance(result, truth["orbit"])
    dev: np.ndarray = np.linalg.norm(z_id - z_true, axis=(1, 2)) / np.linalg.norm(z_true, axis=(1, 2))
    return dev
