"""Terminal progress of a sweep (rich): points, orbit blocks (one per orbit frequency and whirl
direction: the point's blocks), revolutions, ETA.

`SweepProgress` is an event subscriber of the RunEngine; status changes, the run's warnings
(things gone wrong that it survived: an A/D link drop in a block, an acquisition retried; not
its routine notes) and completed points are printed as log lines above the bars. The ETA is
the plan's rig time left (each manual setting counted at its estimate); it does not run down
while the run waits for the operator or is paused, and then says so: 'ETA 12:30 (paused: waiting for the operator)'.
"""

from __future__ import annotations

from rich.console import Console
from rich.text import Text
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from orbitrig.cli.terminal import TerminalConsole
from orbitrig.run.engine import NoteEvent, ProgressEvent, ResultEvent, Severity, StatusEvent
from orbitrig.run.progress import ETA_HELD
from rigunits import format_duration
from orbitrig.run.states import RunState
from orbitrig.store.layout import point_name


class SweepProgress:
    def __init__(self, console: Console | None = None, revolutions: int = 50):
        self.console = console or TerminalConsole(stderr=True)
        self.progress = Progress(
            TextColumn("{task.description:<12}"),
            BarColumn(),
            MofNCompleteColumn(),
            TextColumn("{task.fields[extra]}"),
            TimeElapsedColumn(),
            console=self.console,
            transient=False,
            refresh_per_second=8,
        )
        self.points = self.progress.add_task("points", total=1, extra="")
        self.freqs = self.progress.add_task("orbit blocks", total=1, extra="")
        self.revs = self.progress.add_task("revolutions", total=revolutions, extra="")
        self.revolutions = revolutions  # per block: the revolutions bar's end, until a progress names its block's
        self.done = 0  # points completed in this session (their results)
        self.before = 0  # points of a resumed run measured before it
        self.measured = False  # a point was started (a resumed run with every point done starts none)
        self.eta_s: float | None = None  # wall s of the plan left, as the last progress said
        self.held = ""  # why the ETA stands still (ETA_HELD), "" while it runs down

    def __enter__(self) -> "SweepProgress":
        self.progress.start()
        return self

    def __exit__(self, *exc) -> None:
        if not self.measured:  # nothing was measured: no bars standing at 0 of 1
            for task in (self.points, self.freqs, self.revs):
                self.progress.remove_task(task)
        self.progress.stop()

    def __call__(self, ev) -> None:
        if isinstance(ev, ProgressEvent):
            self.measured, self.eta_s = True, ev.eta_s
            self.before = ev.before  # a resume's points measured before it: done (a point's result comes late)
            done = self.before + self.done
            self.progress.update(self.points, total=max(ev.points, 1), completed=done, extra=self.eta())
            # the blocks acquired (the block under way counted once its acquisition is done), as the
            # dashboard's bar counts them (the event's blocks_done and fraction)
            self.progress.update(self.freqs, total=max(ev.frequencies, 1), completed=ev.blocks_done)
            if ev.block_revolutions > 0:  # the block's own target
                self.revolutions = ev.block_revolutions
            self.progress.update(self.revs, total=self.revolutions, completed=min(ev.revolutions, self.revolutions))
        elif isinstance(ev, StatusEvent):
            style = {RunState.FAULTED: "bold red", RunState.WAITING: "bold yellow", RunState.PAUSED: "yellow"}.get(
                ev.state, ""
            )
            self.progress.console.log(Text(f"{ev.state}: ", style=style) + Text(ev.message))
            self.held = ETA_HELD.get(ev.state, "")
            self.progress.update(self.points, extra=self.eta())
        elif isinstance(ev, ResultEvent):
            p = ev.payload
            self.done += 1
            self.progress.update(self.points, completed=self.before + self.done)
            for task in (self.freqs, self.revs):
                self.progress.update(task, completed=self.progress.tasks[task].total)
            self.progress.console.log(Text(f"point {point_name(p['point'])} {p['label']} complete"))
        elif isinstance(ev, NoteEvent) and ev.severity is Severity.WARNING:
            self.progress.console.log(Text("warning: ", style="bold yellow") + Text(ev.message))

    def eta(self) -> str:
        """The points bar's ETA: 'ETA 12:30', '(paused: waiting for the operator)' after it
        while the run waits; "" before the first estimate."""
        if self.eta_s is None:
            return ""
        return f"ETA {format_duration(self.eta_s)}" + (f" ({self.held})" if self.held else "")
