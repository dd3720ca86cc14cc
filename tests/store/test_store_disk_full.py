"""A sweep whose disk fills up mid-run (a tiny tmpfs, filled by another writer): the
drives are stopped before the storage error is handled, the message is clear, the exit
non-zero without a signal, the completed points stay readable and the run resumes."""

from __future__ import annotations

import asyncio
import time
from pathlib import Path

import pytest

from orbitrig import config as cfg
from orbitrig.cli.simulated_rig import simulated_access
from orbitrig.run.engine import RunEngine, StatusEvent
from orbitrig.store.reader import read_run
from sim.rig import SimRig

from support.cli_helpers import orbitrig, orbitrig_started, reaped
from support.store_checks import check_whole, fill, small_matrix

pytestmark = pytest.mark.timeout(180)

MATRIX = small_matrix("full", revolutions=20, spin_rpm=(1000.0, 1500.0, 2000.0))


def _point_committed(run: Path, index: int) -> bool:
    return (run / "points" / f"{index:04d}" / "complete.json").exists()


def test_disk_full_mid_run_exits_cleanly_and_keeps_the_completed_points(tiny_disk, tmp_path):
    matrix = tmp_path / "full.toml"
    matrix.write_text(MATRIX)
    out = tiny_disk / "run"
    with reaped(orbitrig_started("sweep", "--sim", "--matrix", str(matrix), "--out", str(out), stdin=None)) as proc:
        deadline = time.monotonic() + 60
        while not _point_committed(out, 0):
            assert proc.poll() is None, proc.communicate()[1]
            assert time.monotonic() < deadline, "point 0000 never completed"
            time.sleep(0.005)
        filler = fill(tiny_disk)
        stdout, stderr = proc.communicate(timeout=90)
    assert proc.returncode > 0, f"exit {proc.returncode}\n{stderr}"  # an exit status, not a signal
    assert "Traceback" not in stderr and "Segmentation" not in stderr, stderr
    assert "No space left on device" in stderr and "the disk is full" in stderr, stderr
    run = read_run(out)  # the completed points are readable on the full disk
    assert run.points[0].complete and run.points[0].tables
    assert not all(p.complete for p in run.points)
    filler.unlink()
    p = orbitrig("sweep", "--sim", "--resume", str(out), timeout=120, columns=None)
    assert p.returncode == 0, p.stdout + p.stderr
    check_whole(out, [0, 1, 2], 6)


async def test_drives_are_stopped_before_the_storage_error_is_handled(tiny_disk):
    """At the moment the run reports the storage failure, both drives were already commanded to stop."""
    matrix = cfg.matrix_from_text(MATRIX, "full.toml")
    out = tiny_disk / "run"
    snapshots = []
    async with SimRig(speedup=40.0, adc_pty=False) as sim:
        eng = RunEngine(cfg.load_rig(), out_dir=out, access=simulated_access(sim), confirm_mode="auto")

        def on_event(ev):
            if isinstance(ev, StatusEvent) and ev.state == "faulted":
                snapshots.append((ev.message, sim.drives[1].running, sim.drives[2].running))

        eng.subscribe(on_event)
        run = asyncio.create_task(eng.run(matrix))
        while not _point_committed(out, 0):
            assert not run.done(), run.result()
            await asyncio.sleep(0.005)
        await asyncio.to_thread(fill, tiny_disk)
        outcome = await asyncio.wait_for(run, 90)
    assert outcome.status == "failed"
    assert "disk is full" in outcome.message and str(out) in outcome.message
    assert snapshots, "the failure was never reported"
    message, spin_running, orbit_running = snapshots[0]
    assert "disk is full" in message
    assert not spin_running and not orbit_running, "the drives were still running when the storage error was reported"
    assert read_run(out).points[0].complete
