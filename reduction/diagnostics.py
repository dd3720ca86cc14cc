"""Quality of a fit: reproduced against measured forces (paper Fig. 5), residual RMS."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import overload

import numpy as np
from numpy.typing import ArrayLike

from rigunits import in_hz


FIT_KEYS = ("orbit_hz", "fx_amp_err_pct", "fx_phase_err_deg", "fy_amp_err_pct", "fy_phase_err_deg")


class FitRows(Sequence[dict[str, float | None]]):
    """The ``fit`` entries as a sequence of dicts, kept as columns (NaN for None) so that a
    long table's rows become dicts only when they are read."""

    def __init__(self, columns: dict[str, np.ndarray]):
        self.columns = {k: np.asarray(columns[k], dtype=float) for k in FIT_KEYS}

    def __len__(self) -> int:
        return int(self.columns["orbit_hz"].shape[0])

    @overload
    def __getitem__(self, k: int) -> dict[str, float | None]: ...

    @overload
    def __getitem__(self, k: slice) -> list[dict[str, float | None]]: ...

    def __getitem__(self, k: int | slice) -> dict[str, float | None] | list[dict[str, float | None]]:
        if isinstance(k, slice):
            return [self[i] for i in range(*k.indices(len(self)))]
        return {key: _value(col[k]) for key, col in self.columns.items()}

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Iterable):
            return NotImplemented
        return list(self) == list(other)

    def json_rows(self, start: int, stop: int) -> str:
        """Rows start..stop as JSON objects joined by ", " (NaN written as null): orbit_hz
        exactly, the errors to 7 significant digits (percent and degrees need no more)."""
        cols = [self.columns[k][start:stop].tolist() for k in FIT_KEYS]
        text = ", ".join(
            '{"orbit_hz": %r, "fx_amp_err_pct": %.6e, "fx_phase_err_deg": %.6e, '
            '"fy_amp_err_pct": %.6e, "fy_phase_err_deg": %.6e}' % row
            for row in zip(*cols)
        )
        return text.replace("nan", "null").replace("-inf", "null").replace("inf", "null")


def _value(v: float) -> float | None:
    return float(v) if np.isfinite(v) else None


def fit_errors(orbit: ArrayLike, fx: ArrayLike, fy: ArrayLike, fx_rep: ArrayLike, fy_rep: ArrayLike) -> FitRows:
    """Per orbit frequency: the spec's ``fit`` entries.

    amp_err_pct = 100 (|f_rep| - |f_meas|) / |f_meas|, phase_err_deg = arg(f_rep / f_meas)
    in degrees in (-180, 180] (both signed: reproduced minus measured); None where the
    measured force is zero. orbit in rad/s, reported as orbit_hz.
    """
    cols = {"orbit_hz": in_hz(np.asarray(orbit, dtype=float))}
    for name, meas, rep in (("fx", fx, fx_rep), ("fy", fy, fy_rep)):
        meas, rep = np.asarray(meas, dtype=complex), np.asarray(rep, dtype=complex)
        ok = np.abs(meas) > 0
        safe = np.where(ok, meas, 1.0)
        cols[f"{name}_amp_err_pct"] = np.where(ok, 100 * (np.abs(rep) - np.abs(meas)) / np.abs(safe), np.nan)
        cols[f"{name}_phase_err_deg"] = np.where(ok, np.degrees(np.angle(rep / safe)), np.nan)
    return FitRows(cols)


def residual_rms(fx: ArrayLike, fy: ArrayLike, fx_rep: ArrayLike, fy_rep: ArrayLike) -> float:
    """RMS over the 4n real equations (Re/Im of fx, fy) of measured minus reproduced, N."""
    r = np.concatenate([np.asarray(fx) - np.asarray(fx_rep), np.asarray(fy) - np.asarray(fy_rep)])
    return float(np.sqrt(np.mean(r.real**2 + r.imag**2) / 2))
