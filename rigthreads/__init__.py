"""One BLAS thread per process, in a package of its own: the rule of every entry point (the
orbitrig command, `python -m sim`, the benches, the tests' processes).

numpy and scipy's OpenBLAS starts one thread per core for every matrix product and
factorisation, however small. orbitrig's matrices are small (a few dozen coefficients, a few
hundred rows) and its processes share the cores with the loop that polls the drives, the A/D
decoding and the simulator: on two busy cores the extra threads spin and wait for each other
instead of computing. The five decisions of a sequential point (reduction.completion) took
0.8 to 2.8 s of CPU in all with the default threads and 0.15 to 0.3 s with one, and the rig
idles while each is made. So every process computes with one BLAS thread, unless the environment
already says how many.

The variables are read once, when numpy is first imported (OpenBLAS reads them when it loads):
``one_blas_thread`` is an entry point's first act, never called by a module the application or a
test imports. Like rigerrors and rigunits it imports nothing of ours; unlike them the simulator may
import it too (a thread count shares no sign or scale with the code under test).
"""

from __future__ import annotations

import os

#: the thread-count variables of OpenBLAS, OpenMP builds and MKL
BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def one_blas_thread() -> None:
    """Set each of BLAS_THREAD_VARIABLES to 1 where the environment does not set it."""
    for name in BLAS_THREAD_VARIABLES:
        os.environ.setdefault(name, "1")
