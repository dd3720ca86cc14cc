"""Prompt hand-overs of the interpreter lock in every orbitrig process (the command's other
process-wide rule, one BLAS thread, is rigthreads', which `python -m sim` runs as well).

The storage thread and the identification build files and fits in Python for tens to hundreds
of ms at a time; the loop that polls the drives, woken meanwhile, waited up to Python's default
5 ms for the interpreter lock at each wake-up. ``prompt_lock_handover`` makes it at most
SWITCH_INTERVAL_S (the sweep's speed commands and settle polls began up to 7 ms late).
"""

from __future__ import annotations

import sys

#: s a thread holds the interpreter lock before one waiting for it takes it (Python's default: 5 ms)
SWITCH_INTERVAL_S = 0.001


def prompt_lock_handover() -> None:
    """Lower the interpreter's switch interval to SWITCH_INTERVAL_S (never raise it)."""
    sys.setswitchinterval(min(sys.getswitchinterval(), SWITCH_INTERVAL_S))
