"""The Python API over a stored run: ``orbitrig.open_run(path)`` and
``orbitrig.identify_table(df, model=...)`` (docs/api.md).

:class:`RunData` reads the run once (orbitrig.store.reader, also a run cut short or a
lone run.h5) and gives pandas/xarray views (orbitrig.store.frames) of it; :class:`Fit` is
one identification, stored or made from a table in memory. Plain-data accessors
(:meth:`RunData.fits`, ``RunData.run``) need neither pandas nor xarray.
"""

from __future__ import annotations

import io
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from orbitrig.errors import TableError
from orbitrig.load_systems import LoadSystem
from orbitrig.store import csvfile, frames
from orbitrig.store.fit_record import FitRecord, fit_record, point_fits
from orbitrig.store.errors import RunDirError
from orbitrig.store.index import NEVER_BEGUN
from orbitrig.store.layout import point_name
from orbitrig.store.reader import read_run, read_run_file, stored_channels
from orbitrig.store.selection import unreadable_of
from orbitrig.store.stored_run import Point, Run
from orbitrig.store.truth_data import truth_data
from reduction.methods import Method


class Fit:
    """One identification: ``record`` (arrays) and its tables."""

    def __init__(self, record: FitRecord, truth: dict[str, float] | None = None):
        self.record = record
        self.truth = truth or {}  # coefficient -> true value (--sim runs; csvfile.fit_truth)

    def __repr__(self) -> str:
        r = self.record
        if r.lms is None:  # orbitrig.identify_table: no run, point or load measuring system
            return f"Fit({r.model} {r.freq_dep} {r.method}, from a table in memory)"
        return f"Fit(point={r.point}, {r.key}{', refused' if r.error else ''})"

    @property
    def error(self) -> str:
        """Why the model was refused ("" for a fit)."""
        return self.record.error

    @property
    def result(self) -> dict | None:
        """The whole `identify --json` object (docs/orbit-table.md), with the sweep's additions."""
        return self.record.result

    @property
    def coefficients(self):
        """DataFrame (index ``name``): value, std, U, unit, the budget's parts and, in --sim runs,
        ``true`` (the fit's own truth, as fits.csv's column). SI, one unit per row (the ``unit``
        column and ``attrs["row_units"]``): K in N/m, C in N s/m, D in kg, an Omega^r term's
        times (rad/s)^-r (``N/m (rad/s)^-1``)."""
        return frames.coefficient_table(self.record, self.truth)

    @property
    def covariance(self):
        """DataFrame: the covariance over the free coefficients (their names as index and columns);
        entry (i, j) in unit(i) x unit(j), ``attrs["entry_units"][i][j]`` (``(N/m) * (N s/m)``)."""
        return frames.covariance_frame(self.record)

    @property
    def derived(self):
        """DataFrame (index ``orbit_hz``, Hz): effective damping ``c_eff_xx``, ``c_eff_yy`` (N s/m),
        direct dynamic stiffness ``h_forward``, ``h_backward`` (complex, N/m), whirl frequency
        ratio ``wfr`` (1), each with its standard error; units in ``attrs["units"]``, the C_eff
        zero crossings in attrs ([Omega_0 / 2 pi, its std] in Hz)."""
        return frames.derived_frame(self.record)

    @property
    def adequacy(self) -> dict | None:
        """The frequency-dependence test against the constant fit (verdict, p_value, ...)."""
        return self.record.adequacy

    @property
    def lms_consistency(self) -> dict | None:
        """The two load measuring systems' agreement on this fit (E_n per coefficient, 1; the
        joint chi2 test); None for a table identified in memory."""
        return self.record.lms_consistency


class RunData:
    """A run directory (or a directory holding only run.h5) opened for analysis."""

    def __init__(self, run: Run):
        self.run = run

    def __repr__(self) -> str:
        return f"RunData({str(self.run.directory)!r}, status={self.run.status}, points={len(self.run.points)})"

    def _point(self, point: int) -> Point:
        for p in self.run.points:
            if p.index == point:
                return p
        why = [NEVER_BEGUN] if point in self.run.unbegun else unreadable_of(self.run, point_name(point))
        raise KeyError(
            f"{self.run.directory}: no operating point {point} "
            f"(points: {', '.join(str(p.index) for p in self.run.points) or 'none'})"
            + "".join(f"; point {point_name(point)}: {w}" for w in why)
        )

    @property
    def points(self):
        """DataFrame, one row per operating point (index ``point``): settings, ``spin`` (rad/s),
        ``spin_rpm`` (rpm), ``recess_pressure`` (Pa), the ratios and eccentricities (1),
        ``orbit_radius`` (m), complete, n_frequencies; units in ``attrs["units"]``."""
        return frames.points_frame(self.run.points)

    def table(self, point: int, lms: LoadSystem | str = LoadSystem.PIEZO):
        """DataFrame: the point's orbit table for load measuring system ``lms`` (piezo |
        strain), the orbit-table CSV's columns (``spin_rpm`` rpm, ``orbit_hz`` Hz, phasors and
        ``u_*`` in m and N, coherences 1), ``direction`` and ``block`` (the waveforms' block
        each row was measured in); units in ``attrs["units"]``."""
        p = self._point(point)
        if lms not in p.tables:
            raise KeyError(
                f"point {point} has no orbit table {str(lms)!r} (tables: {', '.join(p.tables) or 'none'})" + _why(p)
            )
        return frames.table_frame(p.tables[LoadSystem(lms)], p.frequencies)  # lms may come as its str value

    def fits(self, point: int | None = None) -> list[FitRecord]:
        """Every stored identification (of one point, or of every complete point) as arrays, SI
        (each coefficient's unit in ``FitRecord.units``)."""
        points = [self._point(point)] if point is not None else self.run.complete_points
        return [f for p in points for f in point_fits(p)]

    @property
    def coefficients(self):
        """DataFrame, one row per (point, lms, model, freq_dep, method): KEY, KEY_std, KEY_U,
        SI: K in N/m, C in N s/m, D in kg, an Omega^r term's (``Kxx_1``) times (rad/s)^-r;
        units in ``attrs["units"]``."""
        return frames.coefficients_frame(self.fits())

    def fit(
        self, point: int, lms: LoadSystem | str, model: str, freq_dep: str = "none", method: Method | str = Method.OLS
    ) -> Fit:
        """One stored identification. KeyError naming the ones there are, as this method takes
        them (``('piezo', 'kc7', 'power:1', 'ols')``)."""
        fits = self.fits(point)
        for f in fits:
            if (f.lms, f.model, f.freq_dep, f.method) == (lms, model, freq_dep, method):
                p = self._point(point)
                return Fit(f, csvfile.fit_truth(f.result, p.truth if self.run.sim else None))
        p = self._point(point)
        there = ", ".join(repr((str(f.lms), f.model, f.freq_dep, str(f.method))) for f in fits)
        raise KeyError(
            f"point {point}: no fit {(str(lms), model, freq_dep, str(method))!r} "
            f"(fits, as fit(point, lms, model, freq_dep, method) takes them: {there or 'none'})" + _why(p)
        )

    def truth(self, point: int) -> dict | None:
        """--sim runs: the simulator's true impedance and its best fits as numpy arrays, SI
        (orbitrig.store.truth_data: ``orbit`` (n,) rad/s, ``Z_re``, ``Z_im`` (n, 2, 2) N/m,
        ``K0``, ``C0``, ``D0`` (2, 2), ``units``); None for a run on the rig. KeyError naming the
        point of a --sim run that stores none (and, for a point the run never completed, why)."""
        p = self._point(point)
        if p.truth is None and self.run.sim:
            raise KeyError(f"point {point} has no truth stored (a --sim run)" + _why(p))
        return truth_data(p.truth)

    def waveforms(self, point: int):
        """xarray Dataset of the point's averaged revolutions (dims block, channel, angle):
        ``mean``, ``dc``, ``phasor``, ``uncertainty`` in each channel's unit, N or m (attributes
        ``units_<channel>``, coordinate ``unit``); ``theta`` in rad, ``orbit_hz`` in Hz. KeyError
        naming a point that stores no block (and, for a point the run never completed, why);
        RunDirError when the run's channels cannot be named (reader.stored_channels)."""
        p = self._point(point)
        if not any("mean" in f.waveform for f in p.frequencies):
            raise KeyError(f"point {point} has no block stored (no waveforms)" + _why(p))
        return frames.waveforms_dataset(p, *stored_channels(self.run))


def _why(p: Point) -> str:
    """The end of a KeyError about point `p`: why it is not complete ("" when it is)."""
    return f"; it is not complete: {p.problem}" if not p.complete else ""


def open_run(path: str | Path) -> RunData:
    """Open the run in ``path`` (docs/api.md): a run directory, or a run file (run.h5 or the h5
    export, under any name). Raises orbitrig.store.reader.RunDirError."""
    if not Path(path).exists():  # either is taken: "no such directory" would send one after a folder
        raise RunDirError(Path(path), "no such run directory or run file")
    return RunData(read_run_file(path) if Path(path).is_file() else read_run(path))


#: the "file" a table in memory is in errors
DATAFRAME = "<DataFrame>"


def _in_frame(err: TableError, df) -> TableError:
    """A table error of the CSV `identify_table` made from `df`, told in the DataFrame's terms:
    the row by position and index label (CSV line 2 is row 0), a header line as the columns,
    an empty cell as NaN."""
    where = DATAFRAME
    if err.line is not None and 2 <= err.line < len(df) + 2:
        where += f", row {err.line - 2} (index {df.index[err.line - 2]!r})"
    reason = err.reason.replace("not a number: ''", "not a number: NaN").replace("from the header", "from the columns")
    return TableError(where, None, err.column, reason)


def _as_frame(df):
    """``df`` as a DataFrame: a DataFrame as it is, a mapping of columns made into one; TypeError
    naming what was given otherwise (an ndarray has no column names)."""
    import pandas as pd

    if isinstance(df, pd.DataFrame):
        return df
    if isinstance(df, Mapping):
        return pd.DataFrame(df)
    raise TypeError(
        f"identify_table takes a pandas DataFrame (or a mapping of columns) with the orbit-table columns "
        f"(spin_rpm, orbit_hz, x_re, ..., fy_im), not {type(df).__module__}.{type(df).__qualname__}"
    )


def identify_table(
    df, model: str = "kcd11", freq_dep: str = "none", method: Method | str = Method.OLS, solver: str = "qr"
) -> Fit:
    """Identify ``model`` from an orbit table in memory: a DataFrame with the orbit-table
    CSV's columns (spin_rpm, orbit_hz, x_re, ..., fy_im; gamma2_*, n_records, u_* optional),
    as RunData.table gives. The Fit has the derived quantities at the table's orbit frequencies
    (on the fit's statistical covariance) and, for a frequency-dependent fit, the adequacy test
    against the constant fit of the same model and method, fitted here (as the sweep does).
    Raises TableError for a bad table, ReductionError for a model the table cannot identify."""
    from orbitrig.store.orbit_table import parse_orbit_table
    from reduction.adequacy import frequency_dependence
    from reduction.derived import derived_quantities
    from reduction.identify import identify
    from reduction.models import CONSTANT

    df = _as_frame(df)
    buf = io.StringIO()
    df.to_csv(buf, index=False)
    try:
        table = parse_orbit_table(buf.getvalue().encode("utf-8"), DATAFRAME)
    except TableError as err:
        raise _in_frame(err, df) from None
    ident = identify(table, model=model, freq_dep=freq_dep, method=method, solver=solver)
    result = ident.to_dict()
    result["derived"] = derived_quantities(ident, np.unique(table.orbit), table.spin).to_dict()
    result["derived"]["covariance"] = "statistical" if ident.covariance is not None else "none"
    if not ident.constant:
        constant = identify(table, model=model, freq_dep=CONSTANT.text, method=method, solver=solver)
        result["adequacy"] = frequency_dependence(constant, ident).to_dict() | {
            "constant": f"{model} {CONSTANT.text} {method}"
        }
    return Fit(fit_record(-1, None, model, freq_dep, method, result))
