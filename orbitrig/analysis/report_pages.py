"""report.pdf's table pages: every reported point's tables as text on A4 portrait pages, before
the figures (a reader who has only the file finds the numbers first), in the figures' font
(orbitrig.analysis.pdf_text: text a reader can copy and search).

They are the rows the page's tables are written from (orbitrig.analysis.table_rows), per point
and load measuring system: the model-adequacy verdicts, every identification (value, standard
error, 95 % interval, systematic u and the expanded U with its k where the run stored a budget,
the simulator's truth, the fit's quality, warnings and notes), the derived quantities; then the
two systems' consistency table. Cells and notes at :data:`TEXT_PT`, headings larger; a negative number with the minus sign
U+2212, as the page (rounding.typeset_minus). A table wider than the page has its column heads
wrapped narrower, then is set smaller, down to the figures' smallest text (FigureStyle.small). Built from the analysis the report makes anyway,
in the report's own process: no figure is drawn for them, none of the figure cache is touched.
"""

from __future__ import annotations

import textwrap
from dataclasses import dataclass

from orbitrig.analysis.pdf_text import Font, figure_font, show, text_width
from orbitrig.analysis.plots import style
from orbitrig.analysis.quality import has_budget
from orbitrig.analysis.report_pdf import provenance_rows
from orbitrig.analysis.reduce import true_constants
from orbitrig.analysis.report_analysis import PointReport, consistency, fit_label
from orbitrig.analysis.rounding import typeset_minus
from orbitrig.analysis.table_rows import (
    NO_BUDGET,
    NO_VERDICT,
    SIGN_CONVENTION,
    Table,
    consistency_rows,
    derived_rows,
    identification_rows,
    verdict_items,
)
from orbitrig.analysis.typeset import operating_point_marked
from orbitrig.load_systems import LMS

#: A4 portrait (pt) and its margin
PAGE = (595.0, 842.0)
MARGIN = 42.0
#: the tables' and notes' text size (pt); headings at 1.15 to 1.35 times it
TEXT_PT = 7.5
#: the size (pt) of the sign convention (table_rows.SIGN_CONVENTION) at the foot of every page
FOOT_PT = 7.0
_LEADING = 1.35  # line height over text size
_PAD = 6.0  # pt between a column's text and the next column
_HEAD_CHARS = 22  # a column head's line, at most (wrapped between words)
#: a column head's line, at most, tried in turn while a table is wider than the page
_HEAD_WRAPS = (_HEAD_CHARS, 16, 12)
_KEEP = "\u00a0"  # a space a head is not wrapped at (between a number and its %), set as a space


@dataclass
class _Line:
    """One line of text (the tables' markup) at `y` (pt below the page's top margin), `x` (pt
    right of its left margin)."""

    text: str
    x: float
    y: float
    size: float
    bold: bool = False
    rule: float = 0.0  # > 0: a rule this long (pt) under the line's baseline instead of text


class TablePages:
    """Lines laid out top down on A4 pages, a block that does not fit the page's rest starting
    a new one, the coefficients' sign convention at the foot of each; :meth:`contents` writes
    each page's PDF operators."""

    def __init__(self) -> None:
        self.width = PAGE[0] - 2 * MARGIN
        self.pages: list[list[_Line]] = [[]]
        self.y = 0.0
        self.fonts = (figure_font(), figure_font(bold=True))
        step, bottom = FOOT_PT * _LEADING, PAGE[1] - 2 * MARGIN
        foot = self.wrap(SIGN_CONVENTION, FOOT_PT)
        self.height = bottom - (len(foot) + 0.8) * step  # the tables' room above the foot
        self.foot_lines = [_Line("", 0.0, self.height + 0.5 * step, FOOT_PT, rule=0.2 * self.width)]
        self.foot_lines += [_Line(w, 0.0, bottom - (len(foot) - 1 - k) * step, FOOT_PT) for k, w in enumerate(foot)]

    def _font(self, bold: bool) -> Font:
        return self.fonts[bold]

    def new_page(self) -> None:
        if self.pages[-1]:
            self.pages.append([])
            self.y = 0.0

    def block(self, lines: list[_Line], height: float) -> None:
        """`lines` (their y from the block's top) as one block `height` pt tall."""
        if self.y + height > self.height:
            self.new_page()
        self.pages[-1] += [_Line(li.text, li.x, li.y + self.y, li.size, li.bold, li.rule) for li in lines]
        self.y += height

    def wrap(self, text: str, size: float, bold: bool = False, indent: float = 0.0) -> list[str]:
        """`text` (markup, its minus signs typeset) in lines as wide as the page less `indent`, broken between words."""
        font, room = self._font(bold), self.width - indent
        space = text_width(font, " ", size)
        lines, line, width = [], "", 0.0
        for word in typeset_minus(text).split(" "):
            w = text_width(font, word, size)
            if line and width + space + w > room:
                lines.append(line)
                line, width = "", 0.0
            line, width = (f"{line} {word}", width + space + w) if line else (word, w)
        return lines + [line]

    def paragraph(self, text: str, size: float = TEXT_PT, bold: bool = False) -> None:
        """`text` (markup) wrapped to the width, a little space after it."""
        step, lines = size * _LEADING, self.wrap(text, size, bold)
        self.block([_Line(w, 0.0, (k + 1) * step, size, bold) for k, w in enumerate(lines)], step * (len(lines) + 0.3))

    def table(self, t: Table) -> None:
        """`t`'s title, head and rows in columns as wide as their widest text (set smaller when
        wider than the page), its quality rows as 'name: value' and its remarks (how to read it)
        under it, on one page; then its warnings and notes."""
        cells = [[typeset_minus(c) for c in row] for row in t.rows]
        head, widths, size = self._fitted(t, cells)
        xs = [sum(widths[:c]) + _PAD * c for c in range(len(widths))]
        step, n_head = size * _LEADING, max(len(h) for h in head)
        title = TEXT_PT * 1.15
        lines = [_Line(t.title, 0.0, title * _LEADING, title, True)]
        top = title * _LEADING + 0.3 * size
        fonts = self.fonts

        def at(c: int, text: str, bold: bool) -> float:  # names and units flush left, numbers flush right
            return xs[c] if c < t.names else xs[c] + widths[c] - text_width(fonts[bold], text, size)

        lines += [
            _Line(x, at(c, x, True), top + (k + 1) * step, size, True)
            for c, h in enumerate(head)
            for k, x in enumerate(h)
        ]
        body = top + n_head * step + 0.3 * size
        full = xs[-1] + widths[-1]
        lines += [_Line("", 0.0, top - 0.1 * size, size, rule=full), _Line("", 0.0, body - 0.1 * size, size, rule=full)]
        for i, row in enumerate(cells):
            y = body + (i + 1) * step
            lines += [
                _Line(text, at(c, text, (i, c) in t.marked), y, size, (i, c) in t.marked) for c, text in enumerate(row)
            ]
        end = body + len(cells) * step + 0.4 * size
        lines.append(_Line("", 0.0, end - 0.1 * size, size, rule=full))
        spans = [w for name, value in t.spans for w in self.wrap(f"{name}: {value}", size, indent=8.0)]
        lines += [_Line(w, 8.0, end + (k + 1) * step, size) for k, w in enumerate(spans)]
        y = end + (len(spans) + 0.6) * step  # the fit's quality on the page of its table
        for remark in t.remarks:  # and how to read it (its ±, its n.d., what D is): a few short sentences
            said = self.wrap(remark, size)
            lines += [_Line(w, 0.0, y + (k + 1) * step, size) for k, w in enumerate(said)]
            y += (len(said) + 0.3) * step
        self.block(lines, y)
        for text in [f"warning: {w}" for w in t.warnings] + t.notes:
            self.paragraph(text, size)

    def _fitted(self, t: Table, cells: list[list[str]]) -> tuple[list[list[str]], list[float], float]:
        """(each column head's lines, each column's width, the text size) of table `t` with `cells`:
        at the tables' size, its heads wrapped narrower (_HEAD_CHARS, then fewer) until the columns fit
        the page's width, else set smaller (to the figures' smallest text) with the narrowest heads."""
        bold = self.fonts[True]
        for size in (TEXT_PT, (TEXT_PT + style().small) / 2, style().small):
            for chars in _HEAD_WRAPS:
                head = [
                    [
                        w.replace(_KEEP, " ")
                        for part in typeset_minus(h).split("\n")
                        for w in textwrap.wrap(
                            part.replace(" %", _KEEP + "%"), chars, break_on_hyphens=False, break_long_words=False
                        )
                    ]
                    for h in t.head
                ]
                widths = [
                    max(
                        [text_width(bold, x, size) for x in head[c]]
                        + [text_width(self.fonts[(i, c) in t.marked], r[c], size) for i, r in enumerate(cells)]
                    )
                    for c in range(len(t.head))
                ]
                if sum(widths) + _PAD * (len(widths) - 1) <= self.width:
                    return head, widths, size
        return head, widths, size

    @property
    def count(self) -> int:
        """How many pages."""
        return sum(1 for lines in self.pages if lines)

    def contents(self) -> list[bytes]:
        """Each page's PDF operators (fonts /F1 regular, /F2 bold), in points from its lower left
        corner, drawing the foot (:meth:`foot`, the form XObject /Foot) last."""
        return [b"\n".join(map(self._operators, lines)) + b"\n/Foot Do" for lines in self.pages if lines]

    def foot(self) -> bytes:
        """The operators of every page's foot, the sign convention: written once, drawn by each page."""
        return b"\n".join(map(self._operators, self.foot_lines))

    def _operators(self, li: _Line) -> bytes:
        x, y = MARGIN + li.x, PAGE[1] - MARGIN - li.y
        if li.rule:
            return b"0.5 w %.2f %.2f m %.2f %.2f l S" % (x, y - 0.3 * li.size, x + li.rule, y - 0.3 * li.size)
        return show(self._font(li.bold), (b"/F1", b"/F2")[li.bold], li.text, x, y, li.size)


def run_header(pages: TablePages, run) -> None:
    """The run's header at the top of the first page, as the page gives it (report_pdf.provenance_rows):
    a referee who has only the file reads which set-up, calibration record, corrections and software."""
    pages.paragraph(f"orbitrig run {run.directory.name}", TEXT_PT * 1.35, bold=True)
    for name, text in provenance_rows(run):
        if text:
            pages.paragraph(f"{name}: {text}")


def point_tables(pages: TablePages, pr: PointReport, run_name: str, fresh: bool = True) -> None:
    """Point `pr`'s tables on `pages`, from a new page (`fresh`; else under what the page holds),
    as the page gives them (the same rows)."""
    p = pr.point
    if fresh:
        pages.new_page()
    pages.paragraph(f"Run {run_name}, point {p.name}: {operating_point_marked(p.settings)}", TEXT_PT * 1.35, bold=True)
    truth = true_constants(p)
    for lms in LMS:
        results = pr.results.get(lms, [])
        if not results:
            continue
        labels = {id(r): fit_label(r) for r in results}
        pages.paragraph(f"{lms} load cells", TEXT_PT * 1.25, bold=True)
        pages.paragraph("Model adequacy", TEXT_PT * 1.15, bold=True)
        items = verdict_items(pr.verdicts.get(lms, []), labels)
        for label, text in items or [("", NO_VERDICT)]:
            pages.paragraph(f"{label}: {text}" if label else text)
        with_budget = has_budget(results)
        for r in results:
            pages.table(identification_rows(r, truth, fit_label(r, name_ols=True), with_budget))
        if not with_budget:
            pages.paragraph(NO_BUDGET)
        derived = derived_rows(pr.derived.get(lms, []), labels, p.settings.spin, p.frequencies)
        if derived is not None:
            pages.table(derived)
    if (compared := consistency(pr)) is not None:
        a, b, comparison = compared
        pages.table(consistency_rows(a, b, comparison, fit_label(a)))


def table_pages(points: list[PointReport], run) -> TablePages:
    """The table pages of `run`: its header, then every point of `points`, each point from a new
    page but the first, under the header."""
    pages = TablePages()
    run_header(pages, run)
    for n, pr in enumerate(points):
        point_tables(pages, pr, run.directory.name, fresh=n > 0)
    return pages
