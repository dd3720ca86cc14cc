"""A run that fails as it starts, after its folder says "running" (the free-space check before
the rig is opened raising another OSError than a full disk: a failing disk's EIO), ends as every
run does: nothing was opened (no drive stopped, none needed), its end is recorded ("failed",
the cause) and the engine is ready for the next run. It left the folder "running" with no end,
the engine's state running, and raised. On the simulated rig with a real run folder; the I/O
error alone is the test's (the first statvfs of the run folder: as root nothing else refuses it)."""

from __future__ import annotations

import errno
import os

import pytest

from orbitrig import config as cfg
from orbitrig.cli.simulated_rig import simulated_access
from orbitrig.run.engine import RunEngine
from orbitrig.store.journal import read_journal
from orbitrig.store.layout import RunLayout
from sim.rig import SimRig
from support.sweep_helpers import SPEEDUP, small_matrix

pytestmark = pytest.mark.timeout(120)


async def test_an_io_error_in_the_start_free_space_check_records_the_runs_end(tmp_path, monkeypatch):
    out, real, calls = tmp_path / "run", os.statvfs, []

    def statvfs(path):
        calls.append(path)
        if len(calls) == 1:
            raise OSError(errno.EIO, os.strerror(errno.EIO), str(path))
        return real(path)

    monkeypatch.setattr(os, "statvfs", statvfs)
    async with SimRig(speedup=SPEEDUP, adc_pty=False) as sim:
        eng = RunEngine(cfg.load_rig(), out_dir=out, access=simulated_access(sim), confirm_mode="auto")
        outcome = await eng.run(small_matrix())
        assert eng.io is None and all(abs(s) < 1.0 for s in sim.speeds)
        j, log = read_journal(RunLayout(out).journal), RunLayout(out).log.read_text()
        state = eng.state
        monkeypatch.undo()
        again = await eng.run(small_matrix(), resume=True)  # the engine is free for the next run
    assert len(calls) >= 1
    assert outcome.status == "failed" and state == "faulted", (outcome, state)
    assert outcome.message.startswith("storage failed: ") and "Input/output error" in outcome.message
    assert j.status == "failed" and j.status_message == outcome.message, (j.status, j.status_message)
    assert "ended: failed: storage failed: " in log, log
    assert again.status == "completed", again.message
