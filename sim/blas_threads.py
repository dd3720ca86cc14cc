"""One BLAS thread per process: the owner of the rule for the orbitrig command
(orbitrig/cli/threads.py says why) and for the simulator's own entry point (`python -m sim`).

It lives in sim because sim imports nothing of the application's and the application may import
sim; only entry points call it (a process's first act, before numpy is imported: OpenBLAS reads
the variables once, when it loads), never a module a test or the application imports.
"""

from __future__ import annotations

import os

#: the thread-count variables of OpenBLAS, OpenMP builds and MKL
BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def one_blas_thread() -> None:
    """Set each of BLAS_THREAD_VARIABLES to 1 where the environment does not set it."""
    for name in BLAS_THREAD_VARIABLES:
        os.environ.setdefault(name, "1")
