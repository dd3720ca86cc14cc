"""Quality of a fit: reproduced against measured forces (paper Fig. 5), residual RMS."""

from __future__ import annotations

import numpy as np


def fit_errors(orbit, fx, fy, fx_rep, fy_rep) -> list[dict]:
    """Per orbit frequency: the spec's ``fit`` entries.

    amp_err_pct = 100 (|f_rep| - |f_meas|) / |f_meas|, phase_err_deg = arg(f_rep / f_meas)
    in degrees in (-180, 180] (both signed: reproduced minus measured); None where the
    measured force is zero. orbit in rad/s, reported as orbit_hz.
    """
    orbit_hz = np.asarray(orbit, dtype=float) / (2 * np.pi)
    cols = {}
    for name, meas, rep in (("fx", fx, fx_rep), ("fy", fy, fy_rep)):
        meas, rep = np.asarray(meas, dtype=complex), np.asarray(rep, dtype=complex)
        ok = np.abs(meas) > 0
        safe = np.where(ok, meas, 1.0)
        amp = 100 * (np.abs(rep) - np.abs(meas)) / np.abs(safe)
        phase = np.degrees(np.angle(rep / safe))
        cols[f"{name}_amp_err_pct"] = [float(a) if o else None for a, o in zip(amp, ok)]
        cols[f"{name}_phase_err_deg"] = [float(p) if o else None for p, o in zip(phase, ok)]
    keys = ("fx_amp_err_pct", "fx_phase_err_deg", "fy_amp_err_pct", "fy_phase_err_deg")
    return [{"orbit_hz": float(f), **{k: cols[k][i] for k in keys}} for i, f in enumerate(orbit_hz)]


def residual_rms(fx, fy, fx_rep, fy_rep) -> float:
    """RMS over the 4n real equations (Re/Im of fx, fy) of measured minus reproduced, N."""
    r = np.concatenate([np.asarray(fx) - fx_rep, np.asarray(fy) - fy_rep])
    return float(np.sqrt(np.mean(r.real**2 + r.imag**2) / 2))
