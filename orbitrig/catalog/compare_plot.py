"""`orbitrig compare`'s figure: coefficients with U bars against one operating variable,
one colour per run (repeats side by side), the repeatability chi2 of each coefficient in
its panel, and predicted values as open black squares joined by a dashed line (a lone
value shows as its square). PNG and PDF through the atomic writer."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from orbitrig.analysis.plots import _colors, panel_figure
from orbitrig.catalog.compare import Row, Variable, repeatability, runs_of
from orbitrig.store.durable import write_atomic

#: plotted unit of each family: (scale from SI, label)
SCALE = {"K": (1e-6, "MN/m"), "C": (1e-3, "kN s/m"), "D": (1.0, "kg")}


def compare_figure(
    rows: list[Row],
    variable: Variable,
    coefficients: list[str],
    *,
    title: str,
    predicted: list[dict[str, float]] | None = None,
):
    """The figure (matplotlib Figure on Agg); rows of one fit kind."""
    ncol = min(4, len(coefficients))
    nrow = -(-len(coefficients) // ncol)
    extra = 0.2 * title.count("\n")  # in: room for each further title line
    fig = panel_figure(
        3.3 * ncol + 0.6, 2.6 * nrow + 2.0 + extra, top=0.75 + extra, bottom=1.0, hspace=0.55, wspace=0.38
    )
    runs = runs_of(rows)
    colors = _colors(len(runs))
    xs = np.array([variable.of(r) for r in rows])
    step = np.min(np.diff(np.unique(xs))) if len(np.unique(xs)) > 1 else 1.0
    offsets = (np.arange(len(runs)) - (len(runs) - 1) / 2) * 0.06 * step  # repeats side by side
    for k, name in enumerate(coefficients):
        ax = fig.add_subplot(nrow, ncol, k + 1)
        scale, unit = SCALE[name[0]]
        for (run_id, run_rows), color, dx in zip(runs.items(), colors, offsets):
            pts = [
                (variable.of(r) + dx, r[name] * scale, (r[f"{name}_U"] or 0.0) * scale)
                for r in run_rows
                if r.get(name) is not None
            ]
            if pts:
                x, y, u = np.array(sorted(pts)).T
                ax.errorbar(x, y, yerr=u, fmt="o-", ms=4, lw=0.8, capsize=3, color=color, label=run_id)
        _draw_predicted(ax, predicted or [], variable, name, scale)
        ax.set_title(f"{name} [{unit}]\n{repeatability(rows, name).text()}", fontsize=8.5)
        ax.set_xlabel(variable.label, fontsize=8)
        ax.tick_params(labelsize=7.5)
        ax.grid(alpha=0.3)
    fig.suptitle(title, fontsize=10)
    handles, labels = fig.axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=min(4, max(1, len(labels))), fontsize=8, frameon=False)
    return fig


def _draw_predicted(ax, predicted: list[dict[str, float]], variable: Variable, name: str, scale: float) -> None:
    column = variable.predicted_column
    pts = sorted((p[column], p[name]) for p in predicted if column in p and np.isfinite(p.get(name, np.nan)))
    if pts:  # a marker on each value: a lone one draws no line
        x, y = np.array(pts).T
        ax.plot(x, y * scale, "k--", marker="s", ms=4, mfc="none", lw=1.2, label="predicted")


def write_figure(fig, out_dir: Path, stem: str = "compare") -> list[Path]:
    """``stem``.png and ``stem``.pdf in ``out_dir``, each written atomically."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    for fmt in ("png", "pdf"):
        buf = io.BytesIO()
        fig.savefig(buf, format=fmt, dpi=120)
        path = out_dir / f"{stem}.{fmt}"
        write_atomic(path, buf.getvalue())
        paths.append(path)
    return paths
