"""Inputs of `orbitrig design`: the per-revolution phasor noise and the prior coefficients.

Noise (standard uncertainty sqrt(E|err|^2) of ONE revolution's complex phasor; SI):
- stated: ``DEFAULT_FORCE_NOISE`` N for fx, fy and ``DEFAULT_PROBE_NOISE`` m for x, y unless
  the command line says otherwise;
- measured (``--noise-from RUN``): from the run's orbit tables of one load measuring system,
  u * sqrt(n_records) per row when the tables carry u_* (orbit-table v2), else the forces'
  noise from the coherence, |f| sqrt((1 - gamma^2) / gamma^2), and the displacements' noise
  as stated. The median over every row of every complete point at each orbit ratio, then
  smoothed across the ratios (reduction.frequency_list.smooth_noise).

Prior coefficients (where the relative standard errors are measured, and where displacement
noise is propagated through Z): the run's identification of the model at the point whose
spin is nearest, else ``NOMINAL``: the order of magnitude of the paper's hydrostatic bearing (D = L = 38.1 mm,
c = 60 um; config/rig.toml [bearing], the simulator's default) at its Table 1 point; D is the film's
inertia alone (the default simulator's recess compressibility makes its apparent D negative).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from orbitrig.load_systems import LoadSystem
from orbitrig.store.layout import point_name
from reduction.frequency_list import predict, smooth_noise

from rigerrors import OrbitrigError
from rigunits import display_unit

DEFAULT_FORCE_NOISE = 20.0  # N per revolution, fx and fy (the simulator's default scenario: 16 to 25 N)
DEFAULT_PROBE_NOISE = 100e-9  # m per revolution, x and y (there: 20 to 160 nm, growing with the orbit ratio)
NOMINAL = {
    "Kxx": 3.8e7,
    "Kxy": 6.0e6,
    "Kyx": -6.0e6,
    "Kyy": 4.0e7,
    "Cxx": 1.0e5,
    "Cxy": 2.0e3,
    "Cyx": 2.0e3,
    "Cyy": 1.1e5,
    "Dxx": 4.0,
    "Dxy": 0.05,
    "Dyx": 0.05,
    "Dyy": 4.2,
}  # (SI; higher orders 0)


class DesignInputError(OrbitrigError):
    """A run that cannot give noise figures (message names the run directory)."""


@dataclass(frozen=True)
class Noise:
    """Per-revolution standard uncertainty of x, y (m), fx, fy (N): (4,) stated, or (m, 4)
    measured at the orbit ratios ``ratios`` (m,); where it came from; the measured orbit
    radius (m, None when stated)."""

    u_revolution: np.ndarray
    source: str
    ratios: np.ndarray | None = None
    radius: float | None = None


def stated_noise(force: float = DEFAULT_FORCE_NOISE, probe: float = DEFAULT_PROBE_NOISE) -> Noise:
    return Noise(
        np.array([probe, probe, force, force], dtype=float),
        f"stated: {force:g} N (forces), {probe * 1e9:g} nm (displacements) per revolution",
    )


def _row_noise(table, probe: float) -> np.ndarray | None:
    """(n, 4) per-revolution noise of one table's rows, or None when it has no evidence."""
    if table.u is not None:
        n = np.full(len(table.orbit), 50.0) if table.n_records is None else np.asarray(table.n_records, float)
        return np.asarray(table.u, dtype=float) * np.sqrt(n)[:, None]
    if table.gamma2 is None:
        return None
    g = np.clip(np.asarray(table.gamma2, dtype=float), 1e-6, 1.0)
    gx, gy = (g[:, 0] + g[:, 1]) / 2, (g[:, 2] + g[:, 3]) / 2
    ufx = np.abs(table.fx) * np.sqrt((1 - gx) / gx)
    ufy = np.abs(table.fy) * np.sqrt((1 - gy) / gy)
    ud = np.full(ufx.shape, probe)
    return np.stack([ud, ud, ufx, ufy], axis=1)


#: measured orbit ratios within this fraction of each other are one set ratio (the drives hold
#: their speeds within [settle] tolerances, so a block's measured ratio scatters about the set one)
SAME_RATIO = 0.005


def _set_ratios(measured: np.ndarray) -> np.ndarray:
    """Each measured |Omega|/omega as the ratio of its group (neighbours, sorted, within SAME_RATIO
    of each other): the group's median at 3 decimals."""
    order = np.argsort(measured, kind="stable")
    ranked = measured[order]
    group = np.concatenate([[0], np.cumsum(np.diff(ranked) > SAME_RATIO * ranked[:-1])])
    out = np.empty_like(measured)
    for g in np.unique(group):
        out[order[group == g]] = np.round(np.median(ranked[group == g]), 3)
    return out


def run_noise(run, lms: LoadSystem, probe: float = DEFAULT_PROBE_NOISE) -> Noise:
    """Median per-revolution noise of the run's ``lms`` orbit tables (complete points)."""
    tables = [p.tables[lms] for p in run.complete_points if lms in p.tables]
    found = [(t, r) for t in tables for r in [_row_noise(t, probe)] if r is not None]
    if not found:
        raise DesignInputError(
            f"{run.directory}: no complete point with an orbit table of the "
            f"{lms} system carrying uncertainties or coherences"
        )
    rows = np.concatenate([r for _, r in found], axis=0)
    ratios = _set_ratios(np.concatenate([np.abs(t.orbit) / t.spin for t, _ in found]))
    at = np.unique(ratios)
    u = smooth_noise(at, np.array([np.median(rows[ratios == r], axis=0) for r in at]))
    radius = float(np.median(np.concatenate([np.sqrt((np.abs(t.x) ** 2 + np.abs(t.y) ** 2) / 2) for t, _ in found])))
    how = "u_* columns" if any(t.u is not None for t, _ in found) else "coherences"
    return Noise(
        u, f"measured: run {run.directory} ({lms}, {how}; median per orbit ratio of {len(rows)} rows)", at, radius
    )


def prior_theta(
    spec, run=None, spin: float | None = None, lms: LoadSystem = LoadSystem.PIEZO
) -> tuple[np.ndarray, str]:
    """(theta in the spec's column order, source): the run's identification of this model
    and frequency dependence at the point nearest ``spin`` (rad/s), else ``NOMINAL``."""
    if run is not None and spin is not None:
        found = []
        for p in run.complete_points:
            ident = p.identification(lms, spec.model, spec.freq_dep.text)
            if ident is not None and ident.result is not None:
                found.append((abs(p.settings.spin - spin), p.index, ident.result.get("coefficients", {})))
        if found:
            _, index, coeffs = min(found, key=lambda f: f[:2])
            if all(coeffs.get(n) is not None for n in spec.names):
                return (
                    np.array([float(coeffs[n]) for n in spec.names]),
                    f"identified: run {run.directory}, point {point_name(index)} ({lms})",
                )
    return np.array([NOMINAL.get(n, 0.0) for n in spec.names]), "nominal (38.1 mm hydrostatic bearing)"


def model_check(spec, run, spin: float, lms: LoadSystem, problem, candidate: tuple, proposal: tuple) -> str | None:
    """A warning when moving from the candidate list to the proposal could move the model's
    estimates by more than the candidate's standard error (reduction.misfit.list_shift):
    the richer model (kcd12 for a model without D; the same model with freq-dep poly:1 for a
    constant model with D) fitted to the run's orbit table at the point nearest ``spin``
    (rad/s) gives the terms the model leaves out; the shift counts with 2 standard
    uncertainties. A list is (ratios, revolutions, directions: each ratio's, in the order of
    the ratios). None when it holds or cannot be judged."""
    from reduction.errors import ReductionError
    from reduction.identify import Method, identify
    from reduction.misfit import list_shift
    from reduction.models import CONSTANT, model_spec

    if run is None or not spec.freq_dep.constant:
        return None
    richer = ("kcd12", CONSTANT.text) if "d" not in spec.model else (spec.model, "poly:1")
    points = [p for p in run.complete_points if lms in p.tables]
    if not points:
        return None
    point = min(points, key=lambda p: (abs(p.settings.spin - spin), p.index))
    table = point.tables[lms]
    try:
        big = identify(
            table, model=richer[0], freq_dep=richer[1], method=Method.WLS if table.u is not None else Method.OLS
        )
        if big.covariance is None:
            return None
        (ra, na, wa), (rb, nb, wb) = candidate, proposal
        a, b = (ra, na, problem.noise_at(ra)), (rb, nb, problem.noise_at(rb))
        sh = list_shift(
            spec, model_spec(*richer), big.theta, big.covariance, problem.spin, problem.radius, a, b, wa, wb
        )
        se = predict(problem, ra, None, wa).std_errors
    except ReductionError:
        return None
    reach = (np.abs(sh.shift) + 2 * sh.std) / se
    j = int(np.argmax(reach))
    if reach[j] <= 1.0:
        return None
    name, model = spec.names[j], spec.model
    unit, k = display_unit(name)  # as the table beside it: MN/m, kN s/m, kg
    shift, std = sh.shift[j] * k, sh.std[j] * k
    where = f"point {point_name(point.index)} of run {run.directory}"
    if abs(sh.shift[j]) > 2 * sh.std[j]:
        return (
            f"the data of {where} show terms {model} leaves out ({' '.join(richer)}): from the candidate list "
            f"to the proposal they move {name} by {shift:.3g} +- {2 * std:.3g} {unit} (2 sigma), up to "
            f"{reach[j]:.2g} x the candidate's standard error: the proposal estimates something else"
        )
    return (
        f"{model} leaves out terms of {' '.join(richer)} that the data of {where} cannot rule out: from the "
        f"candidate list to the proposal they could move {name} by up to {abs(shift) + 2 * std:.3g} {unit} "
        f"({reach[j]:.2g} x the candidate's standard error); compare the two lists on the rig before relying on it"
    )
