"""PNG plots of one operating point (matplotlib, Agg canvas, no pyplot state).

Every figure takes plain data (an OrbitTable, Identification objects from
``reduction.identify``, the point's settings and truth) and writes one PNG.
Axes carry units at the edges: Omega/omega (-), N, deg, MN/m, kN s/m, kg.
Forward whirl is drawn with filled markers and solid lines, backward whirl
with open markers and dashed lines.
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.ticker import MaxNLocator

from orbitrig.analysis.reduce import MATRIX_UNITS
from orbitrig.store.durable import write_atomic
from orbitrig.store.errors import storage_error

ENTRIES = ("xx", "xy", "yx", "yy")
MATRIX_NAMES = {"K": "stiffness", "C": "damping", "D": "apparent inertia (added mass)"}
PAIR_LABELS = {"xfx": "x, Fx", "yfx": "y, Fx", "xfy": "x, Fy", "yfy": "y, Fy"}
DIRECTIONS = ((1, "forward", "-", "o"), (-1, "backward", "--", "s"))
DPI = 110
TRUTH_LABEL = "true (simulator)"


@dataclass
class Fitted:
    """One identification to draw: a legend label and the Identification object."""

    label: str
    identification: Any  # reduction.identify.Identification


def whirl_direction(table) -> np.ndarray:
    """+1 forward / -1 backward per row, from the phasors (forward: y = -i x)."""
    return np.where(np.imag(np.conj(table.x) * table.y) <= 0, 1, -1)


def _figure(w: float, h: float, layout: str | None = "constrained") -> Figure:
    """A figure on an Agg canvas; `layout=None` for many small panels (constrained layout's
    solver costs seconds there), placed by the caller with ``subplots_adjust``."""
    fig = Figure(figsize=(w, h), dpi=DPI, layout=layout)
    FigureCanvasAgg(fig)
    return fig


def panel_figure(w: float, h: float, *, left: float = 0.85, right: float = 0.2, top: float = 0.95,
                 bottom: float = 1.15, wspace: float = 0.42, hspace: float = 0.42) -> Figure:  # fmt: skip
    """A figure of many panels with fixed margins in inches (room for a two-line title on top and
    a legend at the bottom): half the saving time of constrained layout, whose solver measures
    every tick label. Put the legend with ``loc="lower center"``."""
    fig = _figure(w, h, layout=None)
    fig.subplots_adjust(left=left / w, right=1 - right / w, top=1 - top / h, bottom=bottom / h,
                        wspace=wspace, hspace=hspace)  # fmt: skip
    return fig


def save_figure(fig: Figure, path: Path) -> Path:
    """Write `fig` as PNG to `path` (folders created)."""
    return _save(fig, path)


def _save(fig: Figure, path: Path) -> Path:
    """PNG bytes rendered in memory, then written durably (a StorageError names the file)."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise storage_error(path.parent, "create the folder", err) from err
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI)
    write_atomic(path, buf.getbuffer())
    return path


def _colors(n: int) -> list:
    import matplotlib

    cmap = matplotlib.colormaps["tab10"]
    return [cmap(i % 10) for i in range(n)]


def _phase_deg(f: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Phase of a force relative to the x displacement (the paper's phi_x = 0), deg, unwrapped."""
    return np.degrees(np.unwrap(np.angle(f / ref)))


def _near(phase: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Shift each phase by whole turns to lie within 180 deg of ``target``."""
    return phase - 360.0 * np.round((phase - target) / 360.0)


def forces_plot(path, table, fitted: Sequence[Fitted], *, title: str) -> Path:
    """The paper's Figure 5: measured and reproduced force amplitude and phase
    against Omega/omega, for Fx and Fy, one line per identification. When the table has the
    phasor uncertainties u_* the measured points carry error bars of two standard
    uncertainties (amplitude u/sqrt(2), phase u/(sqrt(2)|F|): an isotropic complex error)."""
    fig = _figure(11, 7.5)
    axes = fig.subplots(2, 2, sharex=True)
    ratio = table.orbit / table.spin
    dirs = whirl_direction(table)
    colors = _colors(len(fitted))
    reproduced = [f.identification.reproduce(table) for f in fitted]
    # models that agree draw on top of each other: each later line is thinner, so all stay visible
    widths = [0.9 + 1.0 * (len(fitted) - 1 - k) for k in range(len(fitted))]
    for col, (name, measured) in enumerate((("Fx", table.fx), ("Fy", table.fy))):
        amp_ax, ph_ax = axes[0, col], axes[1, col]
        for d, dname, ls, marker in DIRECTIONS:
            sel = np.flatnonzero(dirs == d)
            if sel.size == 0:
                continue
            sel = sel[np.argsort(ratio[sel])]
            meas_ph = _phase_deg(measured[sel], table.x[sel])
            for k, (fit, rep) in enumerate(zip(fitted, reproduced)):
                f = rep[col][sel]
                amp_ax.plot(ratio[sel], np.abs(f), ls, color=colors[k], lw=widths[k],
                            label=f"{fit.label}" if d == 1 or not np.any(dirs == 1) else None)
                ph_ax.plot(ratio[sel], _near(_phase_deg(f, table.x[sel]), meas_ph), ls, color=colors[k],
                           lw=widths[k])
            face = "black" if d == 1 else "white"
            amp_ax.plot(ratio[sel], np.abs(measured[sel]), marker, mfc=face, mec="black", ls="none",
                        ms=6, label=f"measured, {dname} whirl", zorder=5)
            ph_ax.plot(ratio[sel], meas_ph, marker, mfc=face, mec="black", ls="none", ms=6, zorder=5)
            if table.u is not None:  # +-2 std of the averaged phasor: radial and tangential parts of u
                u = table.u[sel, 2 + col] / np.sqrt(2.0)
                amp_ax.errorbar(ratio[sel], np.abs(measured[sel]), yerr=2 * u, fmt="none", ecolor="black",
                                capsize=3, lw=1, zorder=4, gid="measured-uncertainty")
                ph_ax.errorbar(ratio[sel], meas_ph, yerr=np.degrees(2 * u / np.abs(measured[sel])), fmt="none",
                               ecolor="black", capsize=3, lw=1, zorder=4, gid="measured-uncertainty")
        amp_ax.set_title(f"{name} amplitude")
        amp_ax.set_ylabel(f"|{name}|  [N]")
        ph_ax.set_title(f"{name} phase (relative to x displacement)")
        ph_ax.set_ylabel(f"phase of {name}  [deg]")
        ph_ax.set_xlabel("\u03a9/\u03c9  [-]")
        for ax in (amp_ax, ph_ax):
            ax.grid(True, alpha=0.3)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    if len(set(dirs)) > 1:
        handles += [Line2D([], [], color="gray", ls="-"), Line2D([], [], color="gray", ls="--")]
        labels += ["reproduced, forward (solid)", "reproduced, backward (dashed)"]
    ncols = max(1, min(4, len(labels), 150 // max(len(label) for label in labels)))  # long labels: fewer columns
    fig.legend(handles, labels, loc="outside lower center", ncols=ncols, fontsize=9)
    fig.suptitle(title)
    return _save(fig, path)


def _min_span(ax, largest: float, fraction: float = 0.05) -> None:
    """Make the y axis span at least `fraction` of the matrix's largest entry, so
    that differences far inside the 5 % criterion do not fill a coefficient panel."""
    lo, hi = ax.get_ylim()
    if hi - lo < fraction * largest:
        mid = (lo + hi) / 2
        ax.set_ylim(mid - fraction / 2 * largest, mid + fraction / 2 * largest)


def keep_inside(ax, xs, ys, margin: float = 0.05) -> None:
    """Widen the axes limits so that every point (xs, ys) lies inside, with `margin` of the
    span to spare: truth markers must never fall outside the panel."""
    xs, ys = np.asarray(xs, dtype=float).ravel(), np.asarray(ys, dtype=float).ravel()
    ok = np.isfinite(xs) & np.isfinite(ys)
    if not ok.any():
        return
    for lim, get, put in ((xs[ok], ax.get_xlim, ax.set_xlim), (ys[ok], ax.get_ylim, ax.set_ylim)):
        lo, hi = get()
        span = max(hi - lo, float(np.ptp(lim)), 1e-12)
        if lim.min() <= lo or lim.max() >= hi:
            put(min(lo, lim.min() - margin * span), max(hi, lim.max() + margin * span))


def lms_comparison_plot(path, tables: dict[str, Any], fitted: dict[str, Fitted] | None, *,
                        title: str) -> Path:
    """The two load measuring systems side by side: strain-gauge force relative
    to piezoelectric (amplitude difference in %, phase difference in deg) per
    frequency, and the constant K and C of one identification from each."""
    a, b = tables["piezo"], tables["strain"]
    with_bars = bool(fitted) and len(fitted) == 2
    fig = _figure(12, 7.5 if with_bars else 4.2)
    axes = fig.subplots(2 if with_bars else 1, 2, squeeze=False)
    ratio = a.orbit / a.spin
    dirs = whirl_direction(a)
    colors = _colors(2)
    for c, (name, fa, fb) in enumerate((("Fx", a.fx, b.fx), ("Fy", a.fy, b.fy))):
        rel = fb / fa
        for d, dname, ls, marker in DIRECTIONS:
            sel = np.flatnonzero(dirs == d)
            if sel.size == 0:
                continue
            sel = sel[np.argsort(ratio[sel])]
            axes[0, 0].plot(ratio[sel], 100 * (np.abs(rel[sel]) - 1), ls=ls, marker=marker, color=colors[c],
                            mfc=colors[c] if d == 1 else "white", label=f"{name}, {dname}")
            axes[0, 1].plot(ratio[sel], np.degrees(np.angle(rel[sel])), ls=ls, marker=marker, color=colors[c],
                            mfc=colors[c] if d == 1 else "white", label=f"{name}, {dname}")
    axes[0, 0].set_ylabel("|F strain| / |F piezo| - 1  [%]")
    axes[0, 0].set_title("amplitude difference, strain vs piezo")
    axes[0, 1].set_ylabel("phase(F strain) - phase(F piezo)  [deg]")
    axes[0, 1].set_title("phase difference, strain vs piezo")
    for ax in axes[0]:
        ax.set_xlabel("\u03a9/\u03c9  [-]")
        ax.axhline(0, color="gray", lw=0.8)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    if with_bars:
        width = 0.38
        for col, m in enumerate("KC"):
            ax = axes[1, col]
            unit, scale = MATRIX_UNITS[m]
            keys = [m + e for e in ENTRIES]
            for k, (lms, fit) in enumerate(fitted.items()):
                ident = fit.identification
                vals = [ident.coefficients.get(key, np.nan) * scale for key in keys]
                errs = [(ident.std_errors.get(key) or 0.0) * scale for key in keys]
                ax.bar(np.arange(4) + (k - 0.5) * width, vals, width, yerr=errs, capsize=3,
                       color=colors[k], label=f"{lms}: {fit.label}")
            ax.set_xticks(np.arange(4), keys)
            ax.set_ylabel(f"{MATRIX_NAMES[m]}  [{unit}]")
            ax.set_title(f"{MATRIX_NAMES[m]} identified from each load measuring system")
            ax.axhline(0, color="gray", lw=0.8)
            ax.grid(True, axis="y", alpha=0.3)
            ax.legend(fontsize=8)
    fig.suptitle(title)
    return _save(fig, path)


def summary_plot(path, series: dict[str, list[tuple[int, Any]]], truth: list[tuple[int, dict]], *,
                 model: str, title: str) -> Path:
    """The constant K and C entries of one model at every operating point (x: point
    index), one marker series per load measuring system, error bars of one standard
    error, and the simulator's true values (K0, C0) as black crosses."""
    fig = _figure(13, 6.8)
    axes = fig.subplots(2, 4, sharex=True)
    colors = _colors(len(series))
    offsets = np.linspace(-0.12, 0.12, len(series)) if len(series) > 1 else [0.0]
    largest = {"K": 0.0, "C": 0.0}
    for k, (lms, entries) in enumerate(series.items()):
        idx = np.array([i for i, _ in entries], dtype=float)
        for row, m in enumerate("KC"):
            unit, scale = MATRIX_UNITS[m]
            for col, e in enumerate(ENTRIES):
                key = m + e
                vals = [ident.coefficients.get(key, np.nan) * scale for _, ident in entries]
                largest[m] = max(largest[m], float(np.nanmax(np.abs(vals))))
                errs = [(ident.std_errors.get(key) or 0.0) * scale for _, ident in entries]
                axes[row, col].errorbar(idx + offsets[k], vals, yerr=errs, fmt="o", ms=4, capsize=2,
                                        color=colors[k], label=f"{lms}, {model}")
    for row, m in enumerate("KC"):
        unit, scale = MATRIX_UNITS[m]
        for col, e in enumerate(ENTRIES):
            ax = axes[row, col]
            i, j = divmod(col, 2)
            pts = [(idx, t[f"{m}0"][i][j] * scale) for idx, t in truth if t and f"{m}0" in t]
            if pts:
                ax.plot(*zip(*pts), "x", color="black", ms=6, mew=1.5, label=TRUTH_LABEL)
            ax.set_title(f"{m}{e}")
            ax.set_ylabel(f"{m}{e}  [{unit}]")
            ax.grid(True, alpha=0.3)
            ax.xaxis.set_major_locator(MaxNLocator(integer=True))
            _min_span(ax, largest[m])
            if pts:
                keep_inside(ax, *zip(*pts))
            if row == 1:
                ax.set_xlabel("operating point  [index]")
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncols=len(labels), fontsize=9)
    fig.suptitle(title)
    return _save(fig, path)
