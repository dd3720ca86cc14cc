"""The log of `orbitrig serve` (and of `orbitrig dashboard`): standard error, and with --log-file
a file that rotates.

A service that runs for months must not fill its disk with its own log: the file is
rotated by size (logging.handlers.RotatingFileHandler) when it reaches --log-max-mb and
at most --log-backups older files are kept (LOG.1 ... LOG.N), so the log takes at most
(backups + 1) x max size on disk. A run's own records stay in its run.log.

The records are written by a thread of their own (logging.handlers.QueueListener): a reader of
standard error that stops reading (Ctrl-S at the terminal, a pipe nobody reads) or a log disk
that stalls holds that thread only, never the event loop that carries out (or sends) an abort. Beyond
WAITING_RECORDS records waiting, a record is dropped. `orbitrig serve` sets it up once its options
are checked (a serve refused for them leaves no file, no handler).
"""

from __future__ import annotations

import atexit
import logging
import logging.handlers
import queue
import time
from pathlib import Path

LOG_FORMAT = "%(asctime)s %(levelname)s %(name)s: %(message)s"
DEFAULT_MAX_MB = 10.0  # MB (1e6 bytes) per file
DEFAULT_BACKUPS = 5  # older files kept beside the current one
#: log records waiting for the log's thread; beyond, a record is dropped
WAITING_RECORDS = 10_000


class _HandOver(logging.handlers.QueueHandler):
    """Each record to the log's thread; one with no room is dropped (never waited for)."""

    def enqueue(self, record: logging.LogRecord) -> None:
        try:
            self.queue.put_nowait(record)
        except queue.Full:
            pass


class ServiceLog:
    """The service's log as set up: its records written by a thread of their own (`written`
    waits for them; `close` ends it, the handlers closed)."""

    def __init__(self, handlers: list[logging.Handler]):
        self._waiting: queue.Queue[logging.LogRecord] = queue.Queue(WAITING_RECORDS)
        self._handlers = handlers
        self._hand_over = _HandOver(self._waiting)
        self._listener = logging.handlers.QueueListener(self._waiting, *handlers)
        self._listener.start()
        self._listening = True  # the listener's thread runs (QueueListener.stop() once only)
        logging.getLogger().addHandler(self._hand_over)
        atexit.register(self.close)

    def written(self, timeout: float) -> bool:
        """Wait (at most ``timeout`` wall s) until every record logged so far is written."""
        deadline = time.monotonic() + timeout
        while self._waiting.unfinished_tasks and time.monotonic() < deadline:
            time.sleep(0.01)
        return not self._waiting.unfinished_tasks

    def close(self) -> None:
        """No more records taken; the log's thread ends once those waiting are written, then the
        handlers are closed. Closed again (at the exit, after a command's own close), no thread is
        stopped twice."""
        logging.getLogger().removeHandler(self._hand_over)
        if self._listening:
            try:
                self._listener.stop()
            except queue.Full:  # its reader does not read: the records waiting are not waited for
                return
            self._listening = False
        for handler in self._handlers:
            handler.close()


#: the log `setup_service_log` set up last (`written` waits for it)
_active: ServiceLog | None = None


def setup_service_log(
    *, verbose: bool, log_file: Path | None = None, max_mb: float = DEFAULT_MAX_MB, backups: int = DEFAULT_BACKUPS
) -> ServiceLog:
    """Log to standard error and, given `log_file`, to a rotating file, in a thread of their own.
    Raises OSError when the file cannot be opened (nothing set up then)."""
    global _active
    handlers: list[logging.Handler] = [logging.StreamHandler()]
    if log_file is not None:
        handlers.append(
            logging.handlers.RotatingFileHandler(
                log_file, maxBytes=int(max_mb * 1e6), backupCount=backups, encoding="utf-8"
            )
        )
    for handler in handlers:
        handler.setFormatter(logging.Formatter(LOG_FORMAT))
    level = logging.DEBUG if verbose else logging.INFO
    logging.getLogger().setLevel(level)
    logging.getLogger("mqtt").setLevel(logging.WARNING)
    _active = ServiceLog(handlers)
    return _active


def written(timeout: float) -> bool:
    """Wait (at most ``timeout`` wall s) until the service's log has written every record so far
    (before the process ends without its exit's waits); True without a log set up."""
    return _active is None or _active.written(timeout)
