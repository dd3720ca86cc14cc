"""One BLAS thread per orbitrig process, and prompt hand-overs of the interpreter lock.

numpy and scipy's OpenBLAS starts one thread per core for every matrix product and
factorisation, however small. orbitrig's matrices are small (a few dozen coefficients, a few
hundred rows) and its processes share the cores with the loop that polls the drives, the A/D
decoding and the simulator: on two busy cores the extra threads spin and wait for each other
instead of computing. The five decisions of a sequential point (reduction.completion) took
0.8 to 2.8 s of CPU in all with the default threads and 0.15 to 0.3 s with one, and the rig
idles while each is made. So every command runs with one BLAS thread, unless the environment already says how
many (the variables are read once, when numpy is first imported: ``one_blas_thread`` must run
before that, which is why orbitrig/cli imports numpy only inside its commands). The rule's code
is sim/blas_threads.py, which the simulator's entry point runs as well (sim imports nothing of
orbitrig's).

The storage thread and the identification build files and fits in Python for tens to hundreds
of ms at a time; the loop that polls the drives, woken meanwhile, waited up to Python's default
5 ms for the interpreter lock at each wake-up. ``prompt_lock_handover`` makes it at most
SWITCH_INTERVAL_S (the sweep's speed commands and settle polls began up to 7 ms late).
"""

from __future__ import annotations

import sys

from sim.blas_threads import BLAS_THREAD_VARIABLES, one_blas_thread  # one owner: `python -m sim` sets it too

__all__ = ["BLAS_THREAD_VARIABLES", "SWITCH_INTERVAL_S", "one_blas_thread", "prompt_lock_handover"]

#: s a thread holds the interpreter lock before one waiting for it takes it (Python's default: 5 ms)
SWITCH_INTERVAL_S = 0.001


def prompt_lock_handover() -> None:
    """Lower the interpreter's switch interval to SWITCH_INTERVAL_S (never raise it)."""
    sys.setswitchinterval(min(sys.getswitchinterval(), SWITCH_INTERVAL_S))
