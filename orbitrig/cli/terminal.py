"""The terminal a command prints on, which can go away while the rig runs.

A closed terminal (a hang-up: writes then fail with EIO) or a closed pipe (EPIPE) must not
end a sweep or a calibration half-way: rich's Console raises SystemExit on a broken pipe and
lets any other OSError out of ``print``, from inside a signal handler or the progress bars.
:class:`TerminalConsole` goes quiet instead; the run log keeps the record.
"""

from __future__ import annotations

from rich.console import Console


class TerminalConsole(Console):
    """rich Console that stops writing (``quiet``) when its file fails, instead of raising."""

    def _check_buffer(self) -> None:
        try:
            super()._check_buffer()
        except OSError:
            self.gone()

    def on_broken_pipe(self) -> None:
        self.gone()

    def gone(self) -> None:
        """The terminal is gone: drop what waits to be written and write nothing more."""
        self.quiet = True
        del self._buffer[:]
