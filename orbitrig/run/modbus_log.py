"""pymodbus' own log records: into run.log as debug lines, never raw onto the operator's terminal.

pymodbus logs a failed exchange at error level together with a dump of its
last frames in hex (some twenty lines for one request timeout). Our drives
code already reports what matters in the operator's words (a poll that
failed, a link declared lost), so pymodbus' records are kept for whoever
debugs the link: while a run is open they go to its run.log, each line
marked `debug pymodbus`; outside a run to this module's logger at debug
level. The `pymodbus` logger stops propagating to the root logger (whose
last-resort handler would print them on stderr).
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Iterator
from typing import Protocol

log = logging.getLogger(__name__)


class RunLog(Protocol):
    def log(self, message: str) -> None: ...


class _ToRunLog(logging.Handler):
    def __init__(self) -> None:
        super().__init__(logging.DEBUG)
        self.run_logs: list[RunLog] = []  # the open runs' logs (the latest gets the records)

    def emit(self, record: logging.LogRecord) -> None:
        try:
            text = record.getMessage().strip().replace("\n", "\n    ")
            if self.run_logs:
                self.run_logs[-1].log(f"debug pymodbus {record.levelname.lower()}: {text}")
            else:
                log.debug("pymodbus %s: %s", record.levelname.lower(), text)
        except Exception:  # noqa: BLE001 - logging must never break the run
            self.handleError(record)


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
    h.run_logs.append(run_log)
    try:
        yield
    finally:
        h.run_logs.remove(run_log)
