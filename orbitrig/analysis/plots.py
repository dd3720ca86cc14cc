"""Figures of one operating point (matplotlib, Agg canvas, no pyplot state).

Every figure takes plain data (an OrbitTable, Identification objects from
``reduction.identify``, the point's settings and truth) and is written as a 300 dpi PNG (RGB,
no alpha: report.pdf embeds its pixels as they are), optionally beside a vector PDF and SVG of
the same name (:class:`FigureStyle`: formats, the journal width, the coverage factor of every
band and error bar). Axes carry units at the edges: Omega/omega
(-), N, deg, MN/m, kN s/m, kg. Forward whirl is drawn with filled markers and solid lines,
backward whirl with open markers and dashed lines. Here: the style every figure is drawn in,
a figure's canvas and its saving; the panels and their legend are plot_panels', what is drawn
on a panel plot_marks'.
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass
from enum import StrEnum
from pathlib import Path
from collections.abc import Iterable
from typing import Any, Literal

from matplotlib.figure import Figure

from orbitrig.analysis import plots_narrow as narrow
from orbitrig.analysis.canvas import ReportCanvas, png_bytes
from orbitrig.analysis.typeset import lift_scripts, minus_signs, use_script_scale
from orbitrig.store.durable import write_atomic
from orbitrig.store.errors import storage_error
from orbitrig.store.layout import MATRIX_NAMES as MATRIX_NAMES  # the figures name the matrices as run.h5 does
from reduction.systematic import UncertaintyBasis
from reduction.whirl import Whirl

ENTRIES = ("xx", "xy", "yx", "yy")
DIRECTIONS = ((1, Whirl.FORWARD, "-", "o"), (-1, Whirl.BACKWARD, "--", "s"))
TRUTH_LABEL = "true (simulator)"
#: a journal's print widths (mm): the double column (the page's text width) and the single column
PRINT_WIDTHS_MM = {"single": 85.0, "double": 175.0}
#: journal column widths (in): a figure placed at its print width prints at 100 %, its text at the
#: size the style states (one drawn 7.2 in wide and placed at 175 mm printed its 7 pt at 6.7 pt)
COLUMN_WIDTHS = {name: mm / 25.4 for name, mm in PRINT_WIDTHS_MM.items()}
#: room above and below the data of every panel, a fraction of its y span (matplotlib's 0.05 put
#: markers, error bars' caps and bands 0.5-3 pt from the frame of the narrower panels): every
#: figure's autoscaled y axis takes it (``axes.ymargin`` of :func:`use_style`), limits set by hand
#: to keep points inside take it too (plot_marks.keep_inside)
DATA_ROOM = 0.15


class FigureFormat(StrEnum):
    PNG = "png"
    PDF = "pdf"
    SVG = "svg"


@dataclass(frozen=True)
class FigureStyle:
    """How every figure of a report is drawn and written: ``width`` (in; the journal's double
    column by default), ``formats`` (PNG for the page; PDF and SVG, vector, for print: each
    costs about as much as the PNG again, so they are asked for), PNG resolution (dpi), the text size at that width (pt), the smallest text (pt) and ``coverage``,
    the k of every statistical-only band and error bar and of the measured phasors' (2: U = k u; 1:
    one standard uncertainty; the report's --coverage). A band on the combined covariance takes its
    coefficients' own k instead (:func:`entry_k`, as the table's U)."""

    width: float = COLUMN_WIDTHS["double"]
    formats: tuple[FigureFormat, ...] = (FigureFormat.PNG,)
    dpi: int = 300
    font: float = 7.5
    coverage: float = 2.0
    small: float = 7.0  # the smallest text (pt): tick labels, legends, dense panel titles and table cells

    def band_label(
        self, what: str = "bands and error bars", bases: Iterable[UncertaintyBasis] = (UncertaintyBasis.STATISTICAL,)
    ) -> str:
        """The legend's statement of the uncertainty shown, e.g. 'bands and error bars: expanded
        uncertainty U (k = 2), statistical'; `bases`: what the u of the fits shown rests on (the
        derived quantities' is combined where the run stored a calibration budget). Combined bands
        are at 95.45 % with each coefficient's own k (:func:`entry_k`), statistical ones at the
        style's k."""
        kind = "expanded uncertainty U" if self.coverage != 1 else "standard uncertainty u"
        shown = set(bases)
        parts = [f"{OWN_K}, {BAND_BASIS[UncertaintyBasis.COMBINED]}"] if UncertaintyBasis.COMBINED in shown else []
        if UncertaintyBasis.STATISTICAL in shown or not shown:
            parts.append(f"\u00b1{kind} (k = {self.coverage:g}), {BAND_BASIS[UncertaintyBasis.STATISTICAL]}")
        return f"{what}: " + "; ".join(parts)


#: the legend's words for what a band's standard uncertainty rests on
BAND_BASIS = {
    UncertaintyBasis.COMBINED: "combined (statistical and calibration)",
    UncertaintyBasis.STATISTICAL: "statistical",
}


#: how a legend states the k of a combined band: each coefficient's own, as the table's U
OWN_K = "\u00b1expanded uncertainty U at 95.45 % (k per coefficient: Student's t at its effective dof, as the table)"

STYLE = FigureStyle()


def use_style(style: FigureStyle) -> None:
    """Draw every later figure of this process in `style` (text sizes through rcParams; a label's
    subscripts at its smallest size over its body's, typeset.use_script_scale)."""
    import matplotlib

    global STYLE
    STYLE = style
    matplotlib.rcParams.update(
        {
            "font.size": style.font,
            "axes.titlesize": "medium",
            "axes.labelsize": "medium",
            "xtick.labelsize": style.small,
            "ytick.labelsize": style.small,
            "legend.fontsize": style.small,
            "figure.titlesize": "large",
            "lines.linewidth": 1.0,
            "lines.markersize": 3.5,
            "pdf.fonttype": 42,
            "svg.fonttype": "none",
            "path.simplify": True,
            "axes.ymargin": DATA_ROOM,  # the data clear of the frame in every panel
            "axes.titley": 1.0,  # titles at a fixed height: no search for overlapping tick labels per draw
        }
    )
    use_script_scale(style.small / style.font)  # a label's subscripts at the smallest size, the label at the body's


def style() -> FigureStyle:
    """The style figures are drawn in now (:func:`use_style`)."""
    return STYLE


def coverage() -> float:
    """The coverage factor k of the current style (statistical-only bands are +-k u)."""
    return STYLE.coverage


def entry_k(fit: Fitted, matrix: str, entry: str) -> float:
    """k of the band or error bar of `fit`'s `matrix` `entry` (e.g. "K", "xy"): the largest of its
    coefficients' own k (``fit.ks``; the largest where the entry sums several orders), else the
    style's k (a statistical-only band)."""
    name = matrix + entry
    ks = [v for key, v in (fit.ks or {}).items() if (key == name or key.startswith(name + "_")) and math.isfinite(v)]
    return max(ks) if ks else STYLE.coverage


use_style(STYLE)

#: where every later figure of this process comes from (report_pdf.run_info's Subject: the run, the
#: calibration record and its SHA-256, the software), written into each figure file's metadata
SOURCE = ""


def use_source(text: str) -> None:
    """Write `text` into the metadata of every later figure file of this process (PNG
    Description, PDF Subject, SVG Description), so that a figure shared alone names its run."""
    global SOURCE
    SOURCE = text


def _metadata(fmt: "FigureFormat") -> dict[str, str]:
    """Matplotlib's metadata of a figure file in `fmt` (PDF and SVG take different keys)."""
    about = {"Creator": "orbitrig report"}
    if SOURCE:
        about["Subject" if fmt == FigureFormat.PDF else "Description"] = SOURCE
    return about


@dataclass
class Fitted:
    """One identification to draw: a legend label, the Identification object, in simulator
    runs its own truth (coefficient -> true value: the true Z projected onto its model), and
    the covariance its bands and error bars show (combined where the run stored a budget)."""

    label: str
    identification: Any  # reduction.identify.Identification
    truth: dict[str, float] | None = None
    covariance: Any = None  # the bands' (free coefficients, SI); None: the fit's own
    basis: UncertaintyBasis = UncertaintyBasis.STATISTICAL  # what ``covariance`` rests on
    ks: dict[str, float] | None = (
        None  # each coefficient's k of a combined band (fit_record.expanded_ks); None: the style's
    )


def report_figure(
    w: float,
    h: float,
    layout: Literal["constrained", "compressed", "tight"] | None = "constrained",
    dpi: float | None = None,
) -> Figure:
    """A figure on an Agg canvas of the design size w x h (in) scaled to the style's width;
    `layout=None` for many small panels (constrained layout's solver costs seconds there),
    placed by the caller with ``subplots_adjust``. At the style's PNG resolution unless `dpi`
    says otherwise: its text is measured for the layout (a legend's room, wrapping) as the PNG
    draws it, so each mathtext string is laid out at one resolution and the PNG needs no second one."""
    k = STYLE.width / w
    fig = Figure(figsize=(w * k, h * k), dpi=STYLE.dpi if dpi is None else dpi, layout=layout)
    ReportCanvas(fig)
    return fig


def save_figure(fig: Figure, path: Path) -> Path:
    """Write `fig` to `path` (.png) and beside it in the style's other formats (folders
    created), each rendered in memory, then written durably (a StorageError names the file);
    returns the PNG's path."""
    path = Path(path).with_suffix(".png")
    minus_signs(fig)  # the minus sign print sets, U+2212, in titles and legends as in tick labels
    lift_scripts(fig, STYLE.small)  # before wrapping: the lifted texts are wrapped at their size
    if narrow.is_narrow(STYLE.width):
        narrow.fit_texts(fig)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise storage_error(path.parent, "create the folder", err) from err
    for fmt in (FigureFormat.PNG, *(f for f in STYLE.formats if f != FigureFormat.PNG)):
        if fmt == FigureFormat.PNG:
            text = {"Software": "orbitrig report"} | ({"Description": SOURCE} if SOURCE else {})
            data: bytes | memoryview = png_bytes(fig, STYLE.dpi, text)
        else:
            buf = io.BytesIO()
            fig.savefig(buf, format=str(fmt), dpi=72, metadata=_metadata(fmt))
            data = buf.getbuffer()
        write_atomic(path.with_suffix(f".{fmt}"), data)
    return path
