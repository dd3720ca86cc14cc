"""pymodbus' own log records: into run.log as debug lines, never raw onto the operator's terminal.

pymodbus logs a failed exchange at error level together with a dump of its
last frames in hex (some twenty lines for one request timeout). Our drives
code already reports what matters in the operator's words (a poll that
failed, a link declared lost), so pymodbus' records are kept for whoever
debugs the link: while a run is open they go to its run.log, each line
marked `debug pymodbus`; outside a run to this module's logger at debug
level. The `pymodbus` logger stops propagating to the root logger (whose
last-resort handler would print them on stderr).

A link that keeps timing out makes pymodbus log in bursts (each timeout, each
retry, each frame in hex). Of every burst (records less than BURST_GAP_S apart)
the first BURST_HEAD records are kept, each cut at RECORD_CHARS characters; the
rest is counted, and one line says how many records (and lines) were left out
when the next burst begins or the run's log is detached. run.log therefore
grows by at most BURST_HEAD + 1 records per burst, whatever pymodbus writes.
"""

from __future__ import annotations

import contextlib
import logging
import math
import time
from collections.abc import Callable, Iterator
from typing import Protocol

log = logging.getLogger(__name__)
BURST_GAP_S = 5.0  # s of quiet that end a burst of pymodbus records
BURST_HEAD = 5  # records kept of each burst
RECORD_CHARS = 2000  # characters kept of one record


class RunLog(Protocol):
    def log(self, message: str) -> None: ...


class _ToRunLog(logging.Handler):
    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        super().__init__(logging.DEBUG)
        self.run_logs: list[RunLog] = []  # the open runs' logs (the latest gets the records)
        self.clock = clock
        self._last = -math.inf  # when the last record came (clock s)
        self._kept = self._left_out = self._lines_left_out = 0  # of the current burst

    def emit(self, record: logging.LogRecord) -> None:
        try:
            now = self.clock()
            if now - self._last > BURST_GAP_S:
                self.end_burst()
            self._last = now
            text = record.getMessage().strip()
            if self._kept >= BURST_HEAD:
                self._left_out += 1
                self._lines_left_out += text.count("\n") + 1
                return
            self._kept += 1
            if len(text) > RECORD_CHARS:
                text = f"{text[:RECORD_CHARS]} ... ({len(text) - RECORD_CHARS} characters left out)"
            self._write(f"{record.levelname.lower()}: " + text.replace("\n", "\n    "))
        except Exception:  # noqa: BLE001 - logging must never break the run
            self.handleError(record)

    def end_burst(self) -> None:
        """Close the current burst: one line for the records left out of it (if any)."""
        if self._left_out:
            self._write(f"{self._left_out} more records of this burst left out ({self._lines_left_out} lines)")
        self._kept = self._left_out = self._lines_left_out = 0

    @contextlib.contextmanager
    def held(self) -> Iterator[None]:
        """Hold the handler's lock (logging.Handler's own, under which `emit` runs)."""
        self.acquire()
        try:
            yield
        finally:
            self.release()

    def _write(self, text: str) -> None:
        if self.run_logs:
            self.run_logs[-1].log(f"debug pymodbus {text}")
        else:
            log.debug("pymodbus %s", text)


def _handler() -> _ToRunLog:
    """The one handler on the `pymodbus` logger (installed on first use)."""
    logger = logging.getLogger("pymodbus")
    for h in logger.handlers:
        if isinstance(h, _ToRunLog):
            return h
    h = _ToRunLog()
    logger.addHandler(h)
    logger.propagate = False
    return h


def keep_pymodbus_off_the_terminal() -> None:
    """From now on pymodbus' records go to run.log (in a run) or to debug logging, not to stderr."""
    _handler()


@contextlib.contextmanager
def pymodbus_into(run_log: RunLog) -> Iterator[None]:
    """While inside: pymodbus' records are lines of `run_log` (RunStore.log)."""
    h = _handler()
    with h.held():
        h.end_burst()
        h.run_logs.append(run_log)
    try:
        yield
    finally:
        with h.held():
            h.end_burst()  # the count of a burst goes into the log of the run it happened in
            h.run_logs.remove(run_log)
