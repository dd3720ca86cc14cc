"""A disk that never returns, for a command run as a process (`orbitrig serve`, `orbitrig sweep`):
a sitecustomize module on the process's PYTHONPATH makes its run's block writes hang once the
test creates a flag file (a fault the real parts cannot produce). Only that process: the
variables are taken out of its environment, so the simulator it starts is not touched."""

from __future__ import annotations

from pathlib import Path

from support.paths import ROOT

STALL = """
import os

if os.environ.get("ORBITRIG_TEST_STALL"):
    for name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(name, "1")
    import pathlib
    import threading

    import orbitrig.service.settings as settings
    from orbitrig.store.writer import RunStore

    flag = pathlib.Path(os.environ.pop("ORBITRIG_TEST_STALL"))  # not in the simulator's process
    settings.RECORD_END_S = float(os.environ.pop("ORBITRIG_TEST_RECORD_END_S", settings.RECORD_END_S))
    real = RunStore.write_block

    def write_block(self, point, rec):
        if flag.exists():
            threading.Event().wait()  # a disk that never returns
        return real(self, point, rec)

    RunStore.write_block = write_block
"""


def stalling_env(work: Path, **env: str) -> tuple[dict[str, str], Path]:
    """(environment, flag file): the process's block writes hang once the flag exists;
    ``ORBITRIG_TEST_RECORD_END_S="2"`` among ``env``: the service's allowance for recording a
    run's end (orbitrig.service.settings.RECORD_END_S) in that process."""
    inject = work / "inject"
    inject.mkdir()
    (inject / "sitecustomize.py").write_text(STALL)
    flag = work / "stall"
    return {"PYTHONPATH": f"{inject}:{ROOT}", "ORBITRIG_TEST_STALL": str(flag), **env}, flag
