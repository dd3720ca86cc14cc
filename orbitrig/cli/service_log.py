"""The log of `orbitrig serve`: standard error, and with --log-file a file that rotates.

A service that runs for months must not fill its disk with its own log: the file is
rotated by size (logging.handlers.RotatingFileHandler) when it reaches --log-max-mb and
at most --log-backups older files are kept (LOG.1 ... LOG.N), so the log takes at most
(backups + 1) x max size on disk. A run's own records stay in its run.log.
"""

from __future__ import annotations

import logging
import logging.handlers
from pathlib import Path

LOG_FORMAT = "%(asctime)s %(levelname)s %(name)s: %(message)s"
DEFAULT_MAX_MB = 10.0  # MB (1e6 bytes) per file
DEFAULT_BACKUPS = 5  # older files kept beside the current one


def setup_service_log(
    *, verbose: bool, log_file: Path | None = None, max_mb: float = DEFAULT_MAX_MB, backups: int = DEFAULT_BACKUPS
) -> logging.Handler | None:
    """Log to standard error and, given `log_file`, to a rotating file (returned).
    Raises OSError when the file cannot be opened."""
    level = logging.DEBUG if verbose else logging.INFO
    logging.basicConfig(level=level, format=LOG_FORMAT)
    logging.getLogger().setLevel(level)
    logging.getLogger("mqtt").setLevel(logging.WARNING)
    if log_file is None:
        return None
    handler = logging.handlers.RotatingFileHandler(
        log_file, maxBytes=int(max_mb * 1e6), backupCount=backups, encoding="utf-8"
    )
    handler.setFormatter(logging.Formatter(LOG_FORMAT))
    logging.getLogger().addHandler(handler)
    return handler
