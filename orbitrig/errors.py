"""The application's errors (configuration, orbit tables) and re-exports of the
numerical ones; daq's and drives' branches live in ``daq.errors`` and ``drives.errors``.

    OrbitrigError
    +-- ReductionError (also ValueError) -> IdentificationError -> IdentifiabilityError
    +-- DaqError -> DaqLinkError, DaqTimeoutError (also TimeoutError)
    +-- DriveError(drive, register, fault_code) -> DriveFaultError, DriveLimitError,
    |       DriveLinkError, DriveTimeoutError (also TimeoutError)
    +-- ConfigError (file, key) / TableError (file, line, column) / ExportFileError (file)

IgnoredColumnWarning (a UserWarning, not an error): an orbit-table header column that
looks like a misspelt known column, ignored as every extra column is.
"""

from __future__ import annotations

import os

from reduction.errors import IdentifiabilityError, IdentificationError, ReductionError  # noqa: F401
from rigerrors import OrbitrigError


class ConfigError(OrbitrigError):
    """A configuration or matrix file is invalid; ``problems`` lists each one."""

    def __init__(self, file: str, problems: list[str]):
        self.file = str(file)
        self.problems = list(problems)
        super().__init__("\n".join(f"{self.file}: {p}" for p in self.problems))


class TableError(OrbitrigError, ValueError):
    """A malformed orbit table: names the file, the line (1-based) and the column."""

    def __init__(self, file: str, line: int | None, column: str | None, reason: str):
        self.file, self.line, self.column, self.reason = str(file), line, column, reason
        where = self.file
        if line is not None:
            where += f", line {line}"
        if column is not None:
            where += f", column '{column}'"
        super().__init__(f"{where}: {reason}")


class ExportFileError(OrbitrigError, ValueError):
    """A file given as an orbitrig export that is not one (not readable, not JSON, a key given
    twice, nested too deep, JSON of another kind); ``file`` names it."""

    def __init__(self, file: str | os.PathLike[str], reason: str):
        self.file, self.reason = str(file), reason
        super().__init__(f"{self.file}: {reason}")


class IgnoredColumnWarning(UserWarning):
    """An orbit-table header column that is no known column but looks like one (``suggestion``):
    ignored like any extra column, named so that the misspelling is not passed over."""

    def __init__(self, file: str, line: int, column: str, suggestion: str):
        self.file, self.line, self.column, self.suggestion = str(file), line, column, suggestion
        super().__init__(
            f"{self.file}, line {line}, column '{column}': not an orbit-table column, ignored "
            f"(did you mean '{suggestion}'?)"
        )
