"""Quality of a fit: reproduced against measured forces (paper Fig. 5), residual RMS."""

from __future__ import annotations

import numpy as np


def fit_errors(orbit, fx, fy, fx_rep, fy_rep) -> list[dict]:
    """Per orbit frequency: the spec's ``fit`` entries.

    amp_err_pct = 100 (|f_rep| - |f_meas|) / |f_meas|, phase_err_deg = arg(f_rep / f_meas)
    in degrees in (-180, 180] (both signed: reproduced minus measured); None where the
    measured force is zero. orbit in rad/s, reported as orbit_hz.
    """
    out = []
    for w, a, b, ra, rb in zip(np.asarray(orbit, dtype=float), fx, fy, fx_rep, fy_rep):
        row = {"orbit_hz": float(w / (2 * np.pi))}
        for name, meas, rep in (("fx", a, ra), ("fy", b, rb)):
            if abs(meas) > 0:
                row[f"{name}_amp_err_pct"] = float(100 * (abs(rep) - abs(meas)) / abs(meas))
                row[f"{name}_phase_err_deg"] = float(np.degrees(np.angle(rep / meas)))
            else:
                row[f"{name}_amp_err_pct"] = None
                row[f"{name}_phase_err_deg"] = None
        out.append(row)
    return out


def residual_rms(fx, fy, fx_rep, fy_rep) -> float:
    """RMS over the 4n real equations (Re/Im of fx, fy) of measured minus reproduced, N."""
    r = np.concatenate([np.asarray(fx) - fx_rep, np.asarray(fy) - fy_rep])
    return float(np.sqrt(np.mean(r.real**2 + r.imag**2) / 2))
