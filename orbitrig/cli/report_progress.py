"""`orbitrig report`'s progress on standard error: a bar (points, figures, elapsed, ETA) on a
terminal; when standard error is not a terminal, one closing line only, and none when nothing was
drawn (the report's error says so)."""

from __future__ import annotations

import sys
import time

from orbitrig.cli.terminal import TerminalConsole
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn


class ReportProgress:
    """A context manager whose instance is the report's ``progress(done, total, figures)``."""

    def __init__(self, total: int, stream=None):
        self.stream = stream or sys.stderr
        self.total, self.done, self.figures = total, 0, 0
        self.start = time.monotonic()
        self.bar = None
        if self.stream.isatty() and total > 0:
            self.bar = Progress(
                TextColumn("report"),
                BarColumn(),
                MofNCompleteColumn(),
                TextColumn("points,"),
                TextColumn("{task.fields[figures]} figures"),
                TimeElapsedColumn(),
                TextColumn("ETA"),
                TimeRemainingColumn(),
                console=TerminalConsole(file=self.stream),
                transient=False,
            )
            self.task = self.bar.add_task("report", total=total, figures=0)

    def __enter__(self) -> ReportProgress:
        if self.bar:
            self.bar.start()
        return self

    def __call__(self, done: int, total: int, figures: int) -> None:
        self.done, self.figures = done, figures
        if self.bar:
            self.bar.update(self.task, completed=done, figures=figures)

    def __exit__(self, *exc) -> None:
        if self.bar:
            self.bar.stop()
        elif self.done or self.figures:  # nothing drawn: the report's error line says so, not a count of 0
            self.stream.write(
                f"report: {self.done} of {self.total} point(s), {self.figures} figure(s) drawn "
                f"in {time.monotonic() - self.start:.1f} s\n"
            )
            self.stream.flush()
