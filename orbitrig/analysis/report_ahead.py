"""Report figures drawn during the sweep, as each point completes, so `orbitrig report` after
the sweep reuses them (orbitrig.analysis.report_cache) and draws only what is left.

Drawing costs about 0.3 CPU s per figure (17 figures a point), more than the report of a
large run may take, while the rig spends minutes on each point. :class:`FiguresAhead` hands
the index of each completed point to one drawing process (started at the first point), through
a pipe written without blocking: the loop that polls the drives never waits for it (a full
pipe or a process gone drops the index, and the report draws that point). The process,
``python -m orbitrig.analysis.report_ahead DIR``, takes the lowest CPU priority first (SCHED_IDLE
where the system has it, else nice 19: it runs only on processors nothing else wants), reads
the point from the run's pieces and draws it with the report's default options. ``close`` ends
it with the sweep: a point it had not finished keeps no record and the report draws it.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from orbitrig.errors import OrbitrigError

CLOSE_TIMEOUT_S = 0.5  # for the drawing process to end after SIGTERM, before SIGKILL (at SCHED_IDLE
# on a busy machine it may get no processor to end by itself: the sweep does not wait for it)


def lowest_priority() -> None:
    """This process runs only on processors with nothing else to do (SCHED_IDLE; nice 19 too,
    or alone where SCHED_IDLE is missing). SCHED_IDLE first: from then on the process waits
    for idle processors, even for the nice value it sets next."""
    if hasattr(os, "sched_setscheduler") and hasattr(os, "SCHED_IDLE"):
        try:
            os.sched_setscheduler(0, os.SCHED_IDLE, os.sched_param(0))
        except OSError:  # not permitted here: nice 19 alone
            pass
    os.nice(19 - os.nice(0))


def draw_ahead(directory: Path, index: int, figures: frozenset[str] | None = None) -> bool:
    """Draw the figures of complete point `index` of the run in `directory` (in pieces) as
    `orbitrig report DIR` draws them by default (`figures`: only those kinds), recorded for
    reuse; False when the point is not complete or cannot be read or drawn (the report draws it
    then)."""
    from orbitrig.analysis import plots
    from orbitrig.analysis.report import PLOTS_DIR, ReportOptions, draw_point
    from orbitrig.store.reader import read_run_points

    options = ReportOptions() if figures is None else ReportOptions(figures=figures)
    try:
        run = read_run_points(directory, [index])
        points = [p for p in run.points if p.complete]
        if not points:
            return False
        out = directory / PLOTS_DIR
        out.mkdir(exist_ok=True)
        plots.use_style(options.style)
        draw_point(run, points[0], out, options)
    except (OrbitrigError, OSError):
        return False
    return True


class FiguresAhead:
    """The drawing process of one run directory, fed with the indices of completed points."""

    def __init__(self, directory: Path, figures: frozenset[str] | None = None):
        self.directory = Path(directory)
        self.figures = figures  # the report's kinds to draw (None: all, the report's default)
        self._process: subprocess.Popen | None = None
        self.handed: list[int] = []  # indices handed to the drawing process
        self.dropped: list[int] = []  # indices not handed over (the report draws those points)

    def point_complete(self, index: int) -> None:
        """Hand `index` to the drawing process (started on first use); never blocks."""
        try:
            if self._process is None:
                self._process = subprocess.Popen(
                    [
                        sys.executable,
                        "-m",
                        "orbitrig.analysis.report_ahead",
                        str(self.directory),
                        *sorted(self.figures or ()),
                    ],
                    stdin=subprocess.PIPE,
                    stdout=subprocess.DEVNULL,
                    stderr=subprocess.DEVNULL,
                    start_new_session=True,
                )  # Ctrl-C reaches the sweep only
                assert self._process.stdin is not None
                os.set_blocking(self._process.stdin.fileno(), False)
            assert self._process.stdin is not None
            os.write(self._process.stdin.fileno(), b"%d\n" % index)
            self.handed.append(index)
        except OSError:  # cannot start, pipe full (BlockingIOError) or the process gone
            self.dropped.append(index)

    def on_event(self, event) -> None:
        """A run engine's subscriber: a point's published result (its payload names the point)
        hands that point over."""
        payload = getattr(event, "payload", None)
        if isinstance(payload, dict) and isinstance(payload.get("point"), int):
            self.point_complete(payload["point"])

    @property
    def pid(self) -> int | None:
        """The drawing process's id while it runs (None before the first point)."""
        return None if self._process is None else self._process.pid

    def close(self, *, finish: bool = False) -> None:
        """End the drawing process: at once (SIGTERM, the point it draws is left to the report)
        or, with `finish`, after the points handed over."""
        process, self._process = self._process, None
        if process is None:
            return
        assert process.stdin is not None
        try:
            process.stdin.close()
        except OSError:
            pass
        if not finish:
            process.terminate()
        try:
            process.wait(None if finish else CLOSE_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()


def main(argv: list[str]) -> int:
    """The drawing process (argv: DIR [KIND ...]): lowest priority, then one point per index line
    on stdin until EOF."""
    import signal

    lowest_priority()
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))  # unwinds: no half-written file left
    directory, figures = Path(argv[0]), frozenset(argv[1:]) or None
    for line in sys.stdin:
        if line.strip().isdigit():
            draw_ahead(directory, int(line), figures)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
