"""Benchmarks: speed, latency and memory targets, each a module run from the repository root
as ``python3 -m bench.NAME`` (the root is then on the import path, so a bench imports the
tests' helpers as ``tests.support...`` and another bench as ``bench.NAME``). Each prints its
figures and, where it has a target, exits 1 on a miss. Each runs, as the orbitrig command
does, with one BLAS thread (rigthreads)."""

from rigthreads import one_blas_thread

one_blas_thread()  # as the orbitrig command runs, before a bench imports numpy
