"""Root of orbitrig's exception tree, in a module of its own.

Every package (daq, drives, reduction, the application) may import this one
module; it imports nothing. Each layer derives its own branch from
:class:`OrbitrigError`::

    OrbitrigError
    +-- ReductionError (also ValueError) -> IdentificationError -> IdentifiabilityError   reduction.errors
    +-- DaqError -> DaqLinkError, DaqTimeoutError (also TimeoutError)                      daq.errors
    +-- DriveError(drive, register, fault_code) -> DriveFaultError, DriveLimitError,       drives.errors
    |       DriveLinkError, DriveTimeoutError (also TimeoutError), DriveExceptionResponse
    +-- ConfigError (file, problems), TableError (file, line, column), ExportFileError     orbitrig.errors
"""

from __future__ import annotations


class OrbitrigError(Exception):
    """Base class of every error orbitrig raises on purpose."""
