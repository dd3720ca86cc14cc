"""The run status the store records: the journal's `status` lines and run.h5's `status`
attribute (docs/storage.md). The store owns these words; the run engine maps its outcomes
onto them (orbitrig.run.states.stored_status)."""

from __future__ import annotations

from enum import StrEnum


class RunStatus(StrEnum):
    """A run's stored status; equal to, printed and repr'd as its word (files unchanged).

    `running` from the first journal line until the run ends (also after a crash or a kill),
    then one of completed | stopped | aborted | failed. `unknown` is never written: it is
    what a reader reports for a run.h5 without a status or with a word it does not know.
    """

    __repr__ = str.__repr__

    RUNNING = "running"
    COMPLETED = "completed"
    STOPPED = "stopped"
    ABORTED = "aborted"
    FAILED = "failed"
    UNKNOWN = "unknown"

    @property
    def final(self) -> bool:
        """True once the run has ended (any status but running and unknown)."""
        return self not in (RunStatus.RUNNING, RunStatus.UNKNOWN)

    @classmethod
    def read(cls, word: object) -> RunStatus:
        """The status a file states; `unknown` for a missing or unknown word."""
        try:
            return cls(str(word))
        except ValueError:
            return cls.UNKNOWN
