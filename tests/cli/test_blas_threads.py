"""The orbitrig command computes with one BLAS thread (rigthreads) unless its
environment says how many: numpy's and scipy's OpenBLAS as threadpoolctl reads them in a
fresh process that imported the command."""

from __future__ import annotations

import json
import os
import subprocess
import sys

from rigthreads import BLAS_THREAD_VARIABLES

PROBE = (
    "import json, orbitrig.cli, numpy, scipy.linalg, threadpoolctl; "
    "print(json.dumps([i['num_threads'] for i in threadpoolctl.threadpool_info() if i['user_api'] == 'blas']))"
)


def _blas_threads(env: dict[str, str]) -> list[int]:
    out = subprocess.run([sys.executable, "-c", PROBE], env=env, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout)


def test_one_blas_thread_unless_the_environment_says_how_many():
    bare = {k: v for k, v in os.environ.items() if k not in BLAS_THREAD_VARIABLES}
    threads = _blas_threads(bare)
    assert threads and set(threads) == {1}, threads  # numpy's and scipy's libraries alike
    assert set(_blas_threads({**bare, "OPENBLAS_NUM_THREADS": "2"})) == {2}


def test_the_command_hands_the_interpreter_lock_over_within_a_millisecond():
    """Importing the command lowers Python's 5 ms switch interval to 1 ms (the loop that polls the
    drives waits no longer for a storage thread holding the lock), and never raises a lower one."""
    probe = "import sys; sys.setswitchinterval({}); import orbitrig.cli; print(sys.getswitchinterval())"
    for before, after in ((0.005, 0.001), (0.0005, 0.0005)):
        out = subprocess.run([sys.executable, "-c", probe.format(before)], capture_output=True, text=True, timeout=120)
        assert out.returncode == 0, out.stderr
        assert float(out.stdout) == after


def test_the_test_processes_compute_with_one_blas_thread_too():
    """tests/conftest.py sets the rule before what it imports loads numpy (orbitrig.config does): this
    process's BLAS libraries have the threads the environment said, one where it said none. (With
    orbitrig.config imported first, OpenBLAS had started one thread per core.)"""
    import numpy  # noqa: F401 - loaded already (orbitrig.config): its and scipy's BLAS read below
    import scipy.linalg  # noqa: F401
    import threadpoolctl

    threads = {i["num_threads"] for i in threadpoolctl.threadpool_info() if i["user_api"] == "blas"}
    assert threads == {int(os.environ["OPENBLAS_NUM_THREADS"])}, threadpoolctl.threadpool_info()
