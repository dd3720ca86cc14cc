"""Tables on the terminal that lose nothing: every cell in full, whatever the width.

A :class:`PlainTable` is filled like a rich Table (``add_column``, ``add_row``) and written as
plain text, CSV or JSON (:class:`OutputFormat`). As text, a table wider than the terminal is
split into blocks of columns that fit, each block repeating the key columns (the first
``key_columns``); a cell is never cut, so a single column wider than the terminal is written
whole. The width is the terminal's, or ``COLUMNS``, or 80 when the output is not a terminal.
"""

from __future__ import annotations

import json
import shutil
import textwrap
from collections.abc import Sequence
from dataclasses import dataclass, field
from enum import StrEnum

#: width when standard output is not a terminal and COLUMNS is not set
PIPE_WIDTH = 80
GAP = "  "
#: a space `wrap` never breaks at, written as a space (`unbroken`)
_KEEP = "\u00a0"


class OutputFormat(StrEnum):
    """How a command writes its tables: aligned text, CSV or JSON (one object per table)."""

    TEXT = "text"
    CSV = "csv"
    JSON = "json"


def terminal_width() -> int:
    """Columns of the terminal (``COLUMNS`` wins; :data:`PIPE_WIDTH` when piped)."""
    return shutil.get_terminal_size((PIPE_WIDTH, 24)).columns


def wrap(text: str, width: int | None = None, indent: str | None = None) -> str:
    """`text` folded at spaces to the terminal's width (no word cut: a longer word stays whole),
    continuation lines indented by `indent`: by default the text's own leading spaces and two
    more, so that a nested line's continuation stays under it; a table row passes the indent
    of its last column."""
    lead = text[: len(text) - len(text.lstrip(" "))]
    return textwrap.fill(
        text,
        terminal_width() if width is None else width,
        subsequent_indent=lead + "  " if indent is None else indent,
        break_long_words=False,
        break_on_hyphens=False,
    ).replace(_KEEP, " ")


def unbroken(item: str) -> str:
    """`item` (one entry of a list in a line, e.g. 'settle 1:12:00') kept on one line by `wrap`."""
    return item.replace(" ", _KEEP)


@dataclass
class PlainTable:
    """Column names, right- or left-justified cells (str), an optional title."""

    title: str = ""
    key_columns: int = 1
    columns: list[str] = field(default_factory=list)
    left: list[bool] = field(default_factory=list)
    rows: list[list[str]] = field(default_factory=list)

    def add_column(self, name: str, justify: str = "left") -> None:
        self.columns.append(name)
        self.left.append(justify == "left")

    def add_row(self, *cells: object) -> None:
        row = [str(c) for c in cells]
        self.rows.append(row + [""] * (len(self.columns) - len(row)))

    def text(self, width: int | None = None) -> str:
        """Aligned text, split into column blocks no wider than `width` (default: the terminal's)."""
        width = terminal_width() if width is None else width
        widths = [max([len(c)] + [len(r[i]) for r in self.rows]) for i, c in enumerate(self.columns)]
        keys = list(range(min(self.key_columns, len(self.columns))))
        blocks: list[list[int]] = []
        current: list[int] = []
        used = sum(widths[i] + len(GAP) for i in keys)
        for i in range(len(keys), len(self.columns)):
            if current and used + widths[i] > width:
                blocks.append(current)
                current, used = [], sum(widths[k] + len(GAP) for k in keys)
            current.append(i)
            used += widths[i] + len(GAP)
        blocks.append(current)
        out = [wrap(self.title, width)] if self.title else []
        for n, block in enumerate(blocks):
            cols = keys + block
            if n:
                out.append("")
            for cells in [self.columns] + self.rows:
                line = GAP.join(cells[i].ljust(widths[i]) if self.left[i] else cells[i].rjust(widths[i]) for i in cols)
                out.append(line.rstrip())
        return "\n".join(out)

    def csv(self) -> str:
        from orbitrig.store.csvfile import render_rows

        return render_rows([self.columns, *self.rows]).decode("utf-8").rstrip("\n")

    def records(self) -> list[dict[str, str]]:
        return [dict(zip(self.columns, r)) for r in self.rows]

    def to_dict(self) -> dict:
        return {"title": self.title, "columns": self.columns, "rows": self.records()}


def render(tables: list[PlainTable], fmt: OutputFormat, notes: Sequence[str] = ()) -> str:
    """`tables` (and `notes`, text lines) as `fmt`: text and CSV put a blank line between
    tables (CSV: each table preceded by its title as a '# ' line); JSON is one object
    {"tables": [...], "notes": [...]}."""
    if fmt == OutputFormat.JSON:
        return json.dumps({"tables": [t.to_dict() for t in tables], "notes": list(notes)})
    if fmt == OutputFormat.CSV:
        return "\n\n".join((f"# {t.title}\n" if t.title else "") + t.csv() for t in tables)
    return "\n\n".join([t.text() for t in tables] + (["\n".join(notes)] if notes else []))


class Transcript:
    """Tables and note lines in the order printed (``print`` as rich's Console), written at
    the end in one format: text as printed, CSV tables with notes as '# ' lines, JSON one
    object {"tables", "notes"}."""

    def __init__(self) -> None:
        self.items: list[PlainTable | str] = []

    def print(self, item: PlainTable | str, markup: bool = False) -> None:
        self.items.append(item)

    def write(self, fmt: OutputFormat = OutputFormat.TEXT) -> None:
        tables = [i for i in self.items if isinstance(i, PlainTable)]
        notes = [i for i in self.items if isinstance(i, str)]
        if fmt == OutputFormat.JSON:
            print(render(tables, fmt, notes))
        elif fmt == OutputFormat.CSV:
            print(render(tables, fmt) + "".join(f"\n# {n}" for n in notes))
        else:
            width = terminal_width()
            for item in self.items:
                print(item.text(width) if isinstance(item, PlainTable) else wrap(item, width))
