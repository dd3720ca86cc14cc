"""Figures of derived quantities and of the impedance (matplotlib Agg, no pyplot state).

- :func:`derived_figure`: effective damping C_eff,xx = Cxx - Kxy/Omega and C_eff,yy =
  Cyy + Kyx/Omega with their zero crossings, the whirl frequency ratio, and the forward /
  backward direct dynamic stiffness Re and Im H(Omega) (defined in its caption, the legend's
  title: H = (Z_xx + Z_yy)/2 +- i (Z_yx - Z_xy)/2), each with a band of the expanded
  uncertainty U = k u (u on quality.derived_basis: combined where the run stored a budget, else
  statistical, as the legend says; k on a combined u the fit's own, quality.derived_k, at 95.45 %,
  else the style's, 2 by default), one colour and one marker
  per identification (its zero crossings' markers too, their values in its legend entry, ± the
  fit's own U as the page's table gives it: its k stated where it is not the bands');
- :func:`impedance_figure`: Re and Im of each entry of the identified Z(Omega) = K + i Omega C
  - Omega^2 D, each with its band of the expanded uncertainty U = k u (k: plots.entry_k, the largest
  of the entry's K, C and D coefficients' own k on a combined u; u from the fit's band
  covariance, ``Fitted.covariance``: combined where the run stored a budget, as the legend
  says), against the simulator's true Z at the tested frequencies (black crosses; the Z of
  its reference K, C, D when the run did not store the true Z): a cross outside a band is a
  bias the fit's uncertainty does not cover.

Both return the Figure; x axes are Omega/omega (-); K-like quantities in MN/m, damping in kN s/m;
an impedance panel's y label names its entry with its unit (Re Z_xy  [MN/m], typeset).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from orbitrig.analysis.grid import light_grid
from orbitrig.analysis.plots import ENTRIES, Fitted, coverage, entry_k, style
from orbitrig.analysis.plot_panels import figure_legend, panels
from orbitrig.analysis.plot_marks import (
    series_colors,
    keep_min_span,
    band,
    keep_inside,
    marks_along,
    plot_fit,
    plot_line,
    series_look,
    truth_look,
)
from orbitrig.analysis.quality import TrueImpedance, orbit_grid
from orbitrig.analysis.rounding import number, speed_ratio, with_uncertainty
from reduction.impedance import impedance_basis
from orbitrig.analysis.typeset import entry_math, sub_math
from reduction.derived import Derived
from reduction.systematic import UncertaintyBasis
from rigunits import DISPLAY_UNITS, HZ

NBSP = "\u00a0"  # a no-break space
MN, KNS = DISPLAY_UNITS["K"][1], DISPLAY_UNITS["C"][1]  # N/m -> MN/m, N s/m -> kN s/m


def c_eff(entry: str) -> str:
    """The effective damping of `entry` (xx, yy) as a figure writes it, C<sub>eff,xx</sub>:
    mathtext, upright as the coefficient names beside it."""
    return sub_math("C", f"eff,{entry}")


def h_definition() -> str:
    """What H is, as the derived figure's caption (its legend's title) says it: the direct dynamic
    stiffness of a circular whirl from the identified Z (reduction.derived)."""
    z = entry_math
    return (
        f"H = ({z('Zxx')} + {z('Zyy')})/2 \u00b1 i ({z('Zyx')} \u2212 {z('Zxy')})/2 (Z = K + i\u03a9C \u2212 \u03a9\u00b2D): "
        "+ forward whirl (solid), \u2212 backward (dashed)"
    )


def _band(ax, x, y, std, color, scale, k: float, **kw) -> None:
    """y (solid over the tested range: the derived quantities are formed at the tested |Omega|)
    with its band of the expanded uncertainty k u."""
    plot_line(ax, x, y * scale, color=color, **kw)
    if std is not None:
        band(ax, x, (y - k * std) * scale, (y + k * std) * scale, color=color)


def _zero_text(entry: str, zero, spin: float, k: float | None = None) -> str:
    """Where C_eff of `entry` (xx, yy) crosses zero, as its legend entry says it:
    ``C$_\\mathrm{eff,xx}$ = 0 at 12.19 \u00b1 0.40 Hz, \u03a9/\u03c9 0.732`` (\u00b1 k u: the fit's own k,
    quality.derived_k, as the page's table; None: the style's),
    rounded as the page's table of derived quantities rounds them (rounding.with_uncertainty: U to
    2 significant digits, the value to its decimal; rounding.speed_ratio), a value, its U and unit,
    and the ratio and its value joined by no-break spaces (a narrow figure's legend wraps between
    them, not inside)."""
    if zero is None:
        return f"{c_eff(entry)}: no zero crossing in the tested range"
    w0, sd = zero
    k = coverage() if k is None else k
    value = number(w0 / HZ) if sd is None else with_uncertainty(w0 / HZ, k * sd / HZ)
    return f"{c_eff(entry)} = 0 at {value.replace(' ', NBSP)}{NBSP}Hz, \u03a9/\u03c9{NBSP}{speed_ratio(w0 / spin)}"


def _band_what(ks: Sequence[float], bands: Sequence[float]) -> str:
    """What the legend's statement of k covers: the zero crossings too where each fit's k is its
    bands' (:func:`band_ks`)."""
    return "bands and zero crossings" if all(k == b for k, b in zip(ks, bands)) else "bands"


def band_ks(derived, ks: Sequence[float]) -> list[float]:
    """Each fit's k of its derived bands: its own (`ks`, quality.derived_k: the largest of its
    coefficients', as its zero crossings and the page's table) on a combined u, else the style's."""
    return [k if basis == UncertaintyBasis.COMBINED else coverage() for (*_, basis), k in zip(derived, ks)]


def _zero_entries(derived, ks: Sequence[float], spin: float) -> list[str]:
    """Each fit's legend entry: its label and zero crossings, \u00b1 its own U (k of `ks`), its k
    stated after the label when some fit's k is not the bands' (the legend's title then names
    the bands' k for the bands alone)."""
    state = _band_what(ks, band_ks(derived, ks)) == "bands"
    out = []
    for (label, d, _), k in zip(derived, ks):
        found = {"xx": d.c_eff_zero_xx, "yy": d.c_eff_zero_yy}
        head = f"{label} (\u00b1U, k{NBSP}={NBSP}{k:.3g})" if state else label
        out.append(f"{head}: " + "; ".join(_zero_text(e, z, spin, k) for e, z in found.items()))
    return out


def derived_figure(
    derived: Sequence[tuple[str, Derived, UncertaintyBasis]],
    *,
    spin: float,
    title: str,
    ks: Sequence[float] | None = None,
) -> Figure:
    """C_eff (xx, yy), WFR, Re H and Im H (forward solid, backward dashed) against Omega/omega; each
    entry (label, Derived, the basis of its u: the legend names it); `ks`: each fit's k of its zero
    crossings' \u00b1 U, as the page's table (quality.derived_k; None: the bands', the style's)."""
    fig, axes = panels(14, 9.0, 2, 3, top=1.2, bottom=1.3, hspace=0.6, wspace=0.42)  # y labels clear at 175 mm
    colors, ks = series_colors(len(derived)), [coverage()] * len(derived) if ks is None else list(ks)
    zeros, bks = _zero_entries(derived, ks, spin), band_ks(derived, ks)
    for k, (label, d, _) in enumerate(derived):
        found = {"xx": d.c_eff_zero_xx, "yy": d.c_eff_zero_yy}
        x = d.orbit / spin
        for col, e in enumerate(("xx", "yy")):
            val, std = (d.c_eff_xx, d.c_eff_xx_std) if e == "xx" else (d.c_eff_yy, d.c_eff_yy_std)
            _band(axes[0, col], x, val, std, colors[k], KNS, bks[k], lw=1.1, label=label, **marks_along(k))
            zero = found[e]
            if zero is not None:
                look = {**series_look(k), "ms": 7, "mec": "black", "ls": "none"}
                axes[0, col].plot(zero[0] / spin, 0.0, color=colors[k], zorder=6, **look)
        _band(axes[0, 2], x, d.wfr, d.wfr_std, colors[k], 1.0, bks[k], lw=1.1, label=label, **marks_along(k))
        for col, part in ((0, np.real), (1, np.imag)):
            for h, hstd, ls in ((d.h_forward, d.h_forward_std, "-"), (d.h_backward, d.h_backward_std, "--")):
                std = None if hstd is None else hstd[col]
                _band(axes[1, col], x, part(h), std, colors[k], MN, bks[k], lw=1.1, ls=ls, **marks_along(k))
    for col, e in enumerate(("xx", "yy")):
        ax = axes[0, col]
        ax.axhline(0, color="gray", lw=0.8)
        sign = "\u2212" if e == "xx" else "+"
        # named in the title (its zero crossings: in the legend, under "bands and zero crossings")
        cross = entry_math("K" + ("xy" if e == "xx" else "yx"))
        ax.set_title(f"effective damping {c_eff(e)}\n= {entry_math('C' + e)} {sign} {cross}/\u03a9")
        ax.set_ylabel(f"{c_eff(e)}  [kN s/m]")
    n = entry_math
    axes[0, 2].set_title(f"whirl frequency ratio\n({n('Kxy')} \u2212 {n('Kyx')}) / (\u03c9 ({n('Cxx')} + {n('Cyy')}))")
    axes[0, 2].set_ylabel("WFR  [-]")
    for col, re_im in enumerate(("Re", "Im")):
        axes[1, col].set_title(f"{re_im} H, direct dynamic stiffness\nforward solid, backward dashed")
        axes[1, col].set_ylabel(f"{re_im} H  [MN/m]")
    axes[1, 2].set_visible(False)
    for ax in axes.flat:
        light_grid(ax)
    for ax in axes[1, :2]:
        ax.set_xlabel("\u03a9/\u03c9  [-]")
    axes[0, 2].set_xlabel("\u03a9/\u03c9  [-]")
    for ax in (axes[0, 2], *axes[1, :2]):  # each labelled axis shows its ticks' values (narrow: no panel below Re H)
        ax.xaxis.set_tick_params(labelbottom=True)
    handles = [Line2D([], [], color=c, lw=2, ms=4, **series_look(k)) for k, c in enumerate(colors)]
    figure_legend(
        fig,
        handles,
        zeros,
        ncols=1,
        title=h_definition() + "\n" + style().band_label(_band_what(ks, bks), (basis for *_, basis in derived)),
    )
    fig.suptitle(title)
    return fig


def impedance_std(fit: Fitted, orbit: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """One standard uncertainty of Re Z and of Im Z (each (n, 2, 2), N/m) of `fit` at each
    Omega of `orbit` (rad/s) on its band covariance (the fit's own when it has none stored);
    None without a covariance. Z is linear in the free coefficients: Z = sum_j theta_j E_j."""
    ident = fit.identification
    cov = ident.covariance if fit.covariance is None else fit.covariance
    if cov is None:
        return None
    E = impedance_basis(ident.spec, orbit)  # (n, p, 2, 2)
    cov = np.asarray(cov, dtype=float)
    var = [np.einsum("kpij,pq,kqij->kij", part(E), cov, part(E)) for part in (np.real, np.imag)]
    re_std, im_std = (np.sqrt(np.clip(v, 0, None)) for v in var)
    return re_std, im_std


def impedance_figure(
    fitted: Sequence[Fitted], truth: TrueImpedance, *, spin: float, orbit: np.ndarray, title: str
) -> Figure:
    """Re and Im of Z_xx, Z_xy, Z_yx, Z_yy [MN/m]: identified models (lines, with their bands of
    the style's U = k u) and the simulator's true Z at its frequencies (crosses, kept inside the
    axes)."""
    fig, axes = panels(14, 7.8, 2, 4, bottom=1.0, hspace=0.3, wspace=0.55)
    grid = orbit_grid(orbit)
    colors = series_colors(len(fitted))
    t_w, t_z = truth.orbit, truth.z
    largest = float(np.max(np.abs(t_z))) * MN  # panels span at least 5 % of it: no magnified noise
    lo, hi = (float(v) / spin for v in (np.min(np.abs(orbit)), np.max(np.abs(orbit))))
    for k, fit in enumerate(fitted):
        z = fit.identification.impedance(grid)
        stds = impedance_std(fit, grid)
        for col in range(4):
            i, j = divmod(col, 2)
            for row, take in enumerate((np.real, np.imag)):
                y = take(z[:, i, j]) * MN
                plot_fit(axes[row, col], grid / spin, y, lo, hi, color=colors[k], label=fit.label, marks=marks_along(k))
                if stds is not None:
                    u = max(entry_k(fit, m, ENTRIES[col]) for m in "KCD") * stds[row][:, i, j] * MN
                    band(axes[row, col], grid / spin, y - u, y + u, color=colors[k])
    for col, e in enumerate(ENTRIES):
        i, j = divmod(col, 2)
        for row, (name, part) in enumerate((("Re", np.real), ("Im", np.imag))):
            ax = axes[row, col]
            ax.plot(t_w / spin, part(t_z[:, i, j]) * MN, label=truth.label, **truth_look("large"))
            keep_min_span(ax, largest)
            keep_inside(ax, t_w / spin, part(t_z[:, i, j]) * MN)
            ax.set_title(f"{name} {entry_math('Z' + e)}", fontsize="medium")
            ax.set_ylabel(f"{name} {entry_math('Z' + e)}  [MN/m]")  # as the title names the entry
            light_grid(ax)
            if row == 1:
                ax.set_xlabel("\u03a9/\u03c9  [-]")
    handles, labels = axes[0, 0].get_legend_handles_labels()
    figure_legend(
        fig,
        handles,
        labels,
        ncols=min(3, len(labels)),
        title="identified Z over the tested range (no extrapolation drawn); "
        "f = \u2212Z d, Z = K + i|\u03a9|C \u2212 \u03a9\u00b2D (both whirl directions)\n"
        + style().band_label("bands", (f.basis for f in fitted)),
    )
    fig.suptitle(title)
    return fig
