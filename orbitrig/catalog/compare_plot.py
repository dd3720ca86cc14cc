"""`orbitrig compare`'s figure: coefficients with U bars against one operating variable,
one colour per run (repeats side by side), the repeatability chi2 of each coefficient in
its panel, and predicted values as open black markers joined by a dashed line (a lone
value shows as its marker): only the lines of the plotted rows' conditions, one dashed line
per set of conditions (orbitrig.catalog.predicted). PNG and PDF through the atomic writer.

Typeset as the report's figures (orbitrig.analysis.typeset): each panel's title names its
coefficient subscripted with its unit (K$_\\mathrm{xx}$ [MN/m]), lifted with the x label so
that no subscript prints under the style's smallest text; the repeatability figures are a
line of their own under the title at the smallest text (no subscript to lift), as are the
tick labels and the legend."""

from __future__ import annotations

import io
import math
from pathlib import Path

import matplotlib
import numpy as np
from matplotlib.transforms import Bbox

from orbitrig.analysis.plots import FigureFormat, report_figure, style
from orbitrig.analysis.plot_marks import series_colors
from orbitrig.analysis.typeset import CONDITIONS, condition_math, differing_conditions, entry_math, lift_scripts
from orbitrig.catalog.bearing import bearing_label
from orbitrig.catalog.compare import (
    Row,
    Variable,
    bearing_key,
    coverage,
    curves,
    other_conditions,
    repeatability,
    runs_of,
)
from orbitrig.catalog.predicted import PredictedLines, predicted_lines
from orbitrig.catalog.where import tokens
from orbitrig.store.durable import write_atomic
from orbitrig.store.errors import StorageError, storage_error
from reduction.methods import Method
from reduction.models import is_constant
from rigunits import display_unit

#: height of one row of panels with its titles and labels, and the figure's top and bottom edge (in)
PANEL_HEIGHT, EDGE = 1.9, 0.06

#: gid of the text under each panel's title giving its repeatability chi2
REPEATS = "repeatability"

#: gap (pt) between a panel's top and its repeatability text, and between that and the title
HEAD_GAP = 2.0


def compare_title(rows: list[Row], lms: str, model: str, freq_dep: str, method: str, where: str = "") -> str:
    """The figure's title in the report's words: the fit (its model, a frequency dependence, a
    method other than ols: orbitrig.analysis.report_analysis.fit_label's wording) and load cells,
    how many rows from how many runs, the filter as a reader reads it (`filter_text`), and a second
    line when the K, C, D shown are the constant terms of a frequency-dependent fit."""
    n_rows, n_runs = len(rows), len(runs_of(rows))
    fit = model + ("" if is_constant(freq_dep) else f" {freq_dep}") + ("" if method == Method.OLS else f", {method}")
    return (
        f"Model {fit}, {lms} load cells: {n_rows} row{'s' * (n_rows != 1)} from {n_runs} run{'s' * (n_runs != 1)}"
        + (f" ({filter_text(where)})" if where.strip() else "")
        + ("\nconstant terms (\u03a9\u2070) of a frequency-dependent fit" if not is_constant(freq_dep) else "")
    )


#: a filter's operators as a reader writes them
_OPERATOR_TEXT = {"=": "=", "==": "=", "!=": "\u2260", "<": "<", "<=": "\u2264", ">": ">", ">=": "\u2265"}


def filter_text(where: str) -> str:
    """A --where filter (orbitrig.catalog.where) as a reader reads it, its conditions joined by
    commas: an operating condition by its symbol at its unit (``spin_rpm = 1000``: \u03c9 = 1000 rpm;
    ``recess_pressure > 3e5``: p$_\\mathrm{r}$ > 0.3 MPa), another column in words
    (``matrix_name = eccentricity``: matrix name = eccentricity), the operators as printed (\u2264, \u2265, \u2260)."""
    words = tokens(where)
    parts = []
    for at in range(0, len(words) - 2, 4):  # COLUMN OP VALUE, then "and"
        column, op, value = (t.text for t in words[at : at + 3])
        parts.append(_filter_condition(column, _OPERATOR_TEXT.get(op, op), value))
    return ", ".join(parts)


def _filter_condition(column: str, op: str, value: str) -> str:
    """One condition of a filter (`filter_text`)."""
    try:
        number = float(value)
    except ValueError:
        number = None
    if column in CONDITIONS and number is not None:
        return f"{CONDITIONS[column].math()} {op} {CONDITIONS[column].text(number)}"
    return f"{column.replace('_', ' ')} {op} " + value.replace("$", "\\$")  # text, not mathtext


def compare_figure(
    rows: list[Row],
    variable: Variable,
    coefficients: list[str],
    *,
    title: str,
    predicted: list[dict[str, float]] | None = None,
):
    """The figure (matplotlib Figure on Agg); rows of one fit kind. Text in the report style's
    size (orbitrig.analysis.plots.style) at its width, no glyph under its smallest text (subscripts
    lifted: orbitrig.analysis.typeset.lift_scripts), panels placed by `_lay_out`."""
    ncol = min(4, len(coefficients))
    nrow = -(-len(coefficients) // ncol)
    font, small = style().font, style().small
    fig = report_figure(style().width, PANEL_HEIGHT * nrow, layout=None, dpi=72)  # legend, title: _lay_out, in points
    runs = runs_of(rows)
    lines = predicted_lines(predicted or [], rows, variable)  # those of the plotted rows' conditions
    labels = _run_labels(runs)
    colors = series_colors(len(runs))
    markers = _curve_markers(rows, variable)
    xs = np.array([variable.of(r) for r in rows])
    step = np.min(np.diff(np.unique(xs))) if len(np.unique(xs)) > 1 else 1.0
    offsets = (np.arange(len(runs)) - (len(runs) - 1) / 2) * 0.06 * step  # repeats side by side
    for k, name in enumerate(coefficients):
        ax = fig.add_subplot(nrow, ncol, k + 1)
        unit, scale = display_unit(name)
        for (run_id, run_rows), color, dx in zip(runs.items(), colors, offsets):
            _draw_run(ax, run_rows, variable, name, (scale, dx), color, labels[run_id], markers)
        if k == 0:
            _condition_legend(ax, markers)
        _draw_predicted(ax, lines, variable, name, scale)
        ax.set_title(f"{entry_math(name)} [{unit}]", fontsize=font)
        ax.annotate(
            repeatability(rows, name).text(),
            (0.5, 1.0),
            xycoords="axes fraction",
            xytext=(0.0, HEAD_GAP),
            textcoords="offset points",
            ha="center",
            va="bottom",
            fontsize=small,
            gid=REPEATS,
        )
        ax.set_xlabel(variable.label, fontsize=font)
        ax.tick_params(labelsize=small)
        ax.grid(alpha=0.3)
    lift_scripts(fig, small)  # the titles and x labels with subscripts
    _lay_out(fig, f"{title}\n{bars_text(rows)}", font, small)
    return fig


def bars_text(rows: list[Row]) -> str:
    """What the bars are, for a reader of the figure alone: the stored U with its rows' k
    (2 for a sweep's fits; Student's t for a fit whose covariance came from its residual or whose
    calibration part has few degrees of freedom: each coefficient's, compare.coverage)."""
    ks = sorted({float(f"{coverage(r, c):.3g}") for r in rows for c in _coefficients(r)})
    if len(ks) == 1:
        return f"bars: expanded uncertainty U (k = {ks[0]:g})"
    return f"bars: expanded uncertainty U (each fit's k: {', '.join(f'{k:g}' for k in ks)})"


def _coefficients(row: Row) -> list[str | None]:
    """The coefficients whose U ``row`` gives (None: the row's one k, a row without them)."""
    keys: list[str | None] = [k[:-2] for k, v in row.items() if k.endswith("_U") and v is not None]
    return keys or [None]


def repeats_text(ax):
    """The text under `ax`'s title giving its coefficient's repeatability chi2."""
    return next(t for t in ax.texts if t.get_gid() == REPEATS)


def _raise_titles(fig) -> None:
    """Each panel's title set HEAD_GAP above its repeatability text, measured: the title stands on
    its baseline, and its subscripts reach below it."""
    renderer = fig.canvas.get_renderer()
    for ax in fig.axes:
        repeats = repeats_text(ax).get_window_extent(renderer)
        ax.set_title(ax.get_title(), fontsize=ax.title.get_fontsize(), pad=0.0)
        below = repeats.y1 - ax.title.get_window_extent(renderer).y0  # display units
        ax.set_title(ax.get_title(), fontsize=ax.title.get_fontsize(), pad=below * 72 / fig.dpi + HEAD_GAP)


def _curve_markers(rows: list[Row], variable: Variable) -> dict[tuple, tuple[str, str]]:
    """Each set of the other conditions among ``rows`` -> (marker, legend text naming the
    conditions that tell it from the other sets by symbol and value, ``\u03b2 = 0.25``; "" when
    there is one set)."""
    sets = list(dict.fromkeys(other_conditions(r, variable) for r in rows))
    differ = differing_conditions(sets)
    marks = "osD^v<>ph"
    return {
        s: (marks[i % len(marks)], ", ".join(condition_math(c, v) for c, v in s if c in differ))
        for i, s in enumerate(sets)
    }


def _draw_run(ax, run_rows, variable, name, at, color, label, markers) -> None:
    """One run's values of ``name`` with their U bars: one curve per set of its other
    conditions (compare.curves), each with that set's marker; only the first is labelled.
    ``at``: (scale to the display unit, the run's offset on the x axis)."""
    scale, dx = at
    for conditions, curve in curves(run_rows, variable).items():
        pts = [
            (variable.of(r) + dx, r[name] * scale, _u_or_nan(r.get(f"{name}_U")) * scale)
            for r in curve
            if r.get(name) is not None
        ]
        if pts:
            x, y, u = np.array(sorted(pts)).T
            fmt = markers[conditions][0] + "-"
            ax.errorbar(x, y, yerr=u, fmt=fmt, ms=4, lw=0.8, capsize=3, color=color, label=label)
            label = "_nolegend_"


def _u_or_nan(u: float | None) -> float:
    """A row's U for its bar: NaN (no bar drawn) where it is not known, never a bar of 0 that
    would show the value as exact."""
    return math.nan if u is None else float(u)


def _condition_legend(ax, markers: dict[tuple, tuple[str, str]]) -> None:
    """Grey legend entries naming each set of conditions by its marker, when there are several."""
    if len(markers) > 1:
        for marker, text in markers.values():
            ax.plot([], [], marker=marker, ls="-", lw=0.8, ms=4, color="0.45", label=text)


def _run_labels(runs: dict[str, list[Row]]) -> dict[str, str]:
    """Each run's legend entry: its id, and the bearing it tested when the runs tested more
    than one (`SAC-DS-1@... (sim compressible)`): their points are no repeats of each other."""
    first = {run_id: rows[0] for run_id, rows in runs.items()}
    if len({bearing_key(r) for r in first.values()}) < 2:
        return {run_id: run_id for run_id in runs}
    return {run_id: f"{run_id} ({bearing_label(r)})" for run_id, r in first.items()}


def _lay_out(fig, title: str, font: float, small: float) -> None:
    """The runs' legend at the bottom and `title` at the top, the figure made taller by their
    heights, and the panels between them placed from their measured text (tight_layout, again
    with the tick labels of the new size): no panel's title reaches the tick labels or x label
    of the panel above. tight_layout ignores the titles' width: `_title_overrun` widens the
    edges and the gaps between columns until every title is clear of the next and inside."""
    _raise_titles(fig)
    head = fig.suptitle(title, fontsize=1.2 * font, va="top", in_layout=False)  # the rect below leaves its room
    legend = _legend(fig, small)  # with the title's and its own subscripts lifted
    renderer = fig.canvas.get_renderer()
    extra = legend.get_window_extent(renderer).height + head.get_window_extent(renderer).height
    fig.set_figheight(fig.get_figheight() + extra / fig.dpi + 2 * EDGE)
    head.set_y(1 - EDGE / fig.get_figheight())
    renderer = fig.canvas.get_renderer()  # of the new size
    low = legend.get_window_extent(renderer).y1 / fig.bbox.height
    high = head.get_window_extent(renderer).y0 / fig.bbox.height
    left, right, w_pad = 0.0, 1.0, 0.6
    fig.tight_layout(rect=(left, low, right, high), pad=0.3, h_pad=0.6, w_pad=w_pad)  # then the new tick labels
    for _ in range(4):
        fig.tight_layout(rect=(left, low, right, high), pad=0.3, h_pad=0.6, w_pad=w_pad)
        left_edge, right_edge, between = _title_overrun(fig, EDGE * fig.dpi)
        if max(left_edge, right_edge, between) < 0.5:  # display units: points at dpi 72
            return
        ncol = fig.axes[0].get_subplotspec().get_gridspec().ncols
        # 1.25: the panels narrow as the edges come in, and their titles overhang more
        left, right = left + 1.25 * left_edge / fig.bbox.width, right - 1.25 * right_edge / fig.bbox.width
        w_pad += 1.25 * ncol * between / fig.dpi * 72 / matplotlib.rcParams["font.size"]  # tight_layout's unit


def _legend(fig, size: float):
    """The runs' legend at the bottom (text `size` pt) in as many columns (at most 4) as fit in the
    figure's width: run ids are long (`SAC-DS-1@2026-12-03T17:46:24.468Z`), and a legend wider than
    the figure is cut at both edges when written."""
    handles, labels = fig.axes[0].get_legend_handles_labels()
    room, ncol = fig.bbox.width - 2 * EDGE * fig.dpi, min(4, max(1, len(labels)))
    legend = fig.legend(handles, labels, loc="lower center", ncol=ncol, fontsize=size, frameon=False)
    lift_scripts(fig, size)  # a condition's subscript (\u03b5$_\\mathrm{d}$ = 0.1), the title's
    while ncol > 1 and legend.get_window_extent(fig.canvas.get_renderer()).width > room:
        legend.remove()
        ncol -= 1
        legend = fig.legend(handles, labels, loc="lower center", ncol=ncol, fontsize=size, frameon=False)
        lift_scripts(fig, size)
    return legend


def _head_extent(ax, renderer):
    """The box (display units) of `ax`'s title and the repeatability text under it."""
    return Bbox.union([ax.title.get_window_extent(renderer), repeats_text(ax).get_window_extent(renderer)])


def _title_overrun(fig, pad: float) -> tuple[float, float, float]:
    """How far (display units) a panel's title or repeatability text runs past the figure's left
    edge, its right edge, and into the next panel's of its row, each less `pad`; 0 where it does not."""
    renderer = fig.canvas.get_renderer()
    spans = {}
    for ax in fig.axes:
        spec = ax.get_subplotspec()
        spans[spec.rowspan.start, spec.colspan.start] = _head_extent(ax, renderer)
    last = max(col for _, col in spans)
    left = max(pad - b.x0 for (_, col), b in spans.items() if col == 0)
    right = max(b.x1 + pad - fig.bbox.width for (_, col), b in spans.items() if col == last)
    between = [b.x1 + pad - spans[row, col + 1].x0 for (row, col), b in spans.items() if (row, col + 1) in spans]
    return max(left, 0.0), max(right, 0.0), max([*between, 0.0])


def _draw_predicted(ax, lines: PredictedLines, variable: Variable, name: str, scale: float) -> None:
    """One dashed line per set of conditions (predicted_lines); when several, each labelled
    with the conditions that tell it from the others and given its own marker."""
    column = variable.predicted_column
    differing = differing_conditions(given for given, _ in lines)
    for (given, table), marker in zip(lines, "s^Dvo<>"):
        pts = sorted((p[column], p[name]) for p in table if column in p and np.isfinite(p.get(name, np.nan)))
        if pts:  # a marker on each value: a lone one draws no line
            x, y = np.array(pts).T
            label = ", ".join(["predicted", *(condition_math(c, v) for c, v in given if c in differing)])
            ax.plot(x, y * scale, "k--", marker=marker, ms=4, mfc="none", lw=1.2, label=label)


def write_figure(fig, out_dir: Path, stem: str = "compare") -> list[Path]:
    """``stem``.png and ``stem``.pdf in ``out_dir`` (made when missing), each written atomically.
    Raises StorageError naming ``out_dir`` when it is not a directory or cannot be made."""
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise StorageError(out_dir, "cannot write the figures there: not a directory (--out names a folder)")
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise storage_error(out_dir, "create the folder", err) from err
    paths = []
    for fmt in (FigureFormat.PNG, FigureFormat.PDF):
        buf = io.BytesIO()
        fig.savefig(buf, format=fmt, dpi=120)
        path = out_dir / f"{stem}.{fmt}"
        write_atomic(path, buf.getvalue())
        paths.append(path)
    return paths
