"""A signal at the terminal of `orbitrig sweep` after the run has closed the drives is not dropped.

The run's cleanup could not confirm the drives stopped (their ramp stop lasts minutes): the run
ends failed, "drives not confirmed stopped", and while it records its end (state faulted) the
operator presses Ctrl-C or sends SIGTERM (again). The run no longer holds the drives, so its abort
reaches nothing; the terminal's operator then sends both drives the emergency stop (OFF3) over a
link of its own, as `orbitrig serve` does for such an abort, and prints which drives took it.

Real parts: the simulator process (as `sweep --sim` runs it) over real Modbus TCP, the run engine,
real signals to this process reaching the operator's handlers.
"""

from __future__ import annotations

import asyncio
import io
import os
import signal
import sys
import time

import pytest
from rich.console import Console

from orbitrig import config as cfg
from orbitrig.cli.operator import Operator
from orbitrig.run.drive_setup import bare_drives, modbus_link
from orbitrig.run.engine import RunEngine, StatusEvent
from orbitrig.run.states import RunState
from support.sweep_helpers import SimulatorView, small_matrix, wait_for

pytestmark = pytest.mark.timeout(240)
CW_EMERGENCY = 0x047B  # spec control word, written out on purpose
DECEL_S = 1800.0  # both drives' DECEL_TIME (its longest): 0.6 s per rpm, simulated
SPEEDUP = 10.0  # from 190 rpm and more: 11 s and more here, twice what the run's cleanup waits for standstill


async def slow_ramp_stop(url: str, drives) -> None:
    link = modbus_link(url, drives)
    try:
        await link.connect()
        for drive in bare_drives(link, drives):
            await drive.configure(decel_time=DECEL_S)
    finally:
        await link.close()


def emergency_words_since(view: SimulatorView, t0: float) -> dict[int, list[int]]:
    return {dev: [cw for t, cw in view.drive(dev)["control_words"] if t >= t0 and cw == CW_EMERGENCY] for dev in (1, 2)}


@pytest.mark.parametrize(
    "first, late", [("SIGTERM", signal.SIGTERM), ("stop", signal.SIGINT)], ids=["sigterm-twice", "stop-then-ctrl-c"]
)
async def test_a_signal_after_the_run_closed_the_drives_sends_the_emergency_stop(tmp_path, monkeypatch, first, late):
    from orbitrig.cli.simulated_rig import simulated_rig

    read_end, write_end = os.pipe()  # the operator's terminal: open, nothing typed
    monkeypatch.setattr(sys, "stdin", os.fdopen(read_end))
    rig = cfg.load_rig()
    rig = rig.model_copy(update={"drives": rig.drives.model_copy(update={"stop_timeout_s": 2.0})})
    async with simulated_rig(SPEEDUP) as (sim, access):
        view = SimulatorView(sim)
        await slow_ramp_stop(access.endpoints.modbus_url, rig.drives)
        eng = RunEngine(rig, out_dir=tmp_path / "run", access=access, confirm_mode="auto")
        out = io.StringIO()
        operator = Operator(eng, Console(file=out, width=300))
        eng.subscribe(operator.on_event)
        late_at: list[float] = []

        def at_the_fault(ev) -> None:  # the run has closed the drives and records its end
            if isinstance(ev, StatusEvent) and ev.state == RunState.FAULTED and not late_at:
                late_at.append(time.monotonic())
                os.kill(os.getpid(), late)

        eng.subscribe(at_the_fault)
        operator.install()
        try:
            run = asyncio.create_task(eng.run(small_matrix()))
            await wait_for(lambda: min(abs(w) for w in view.speeds) > 20.0, 120, "both drives turning")
            if first == "SIGTERM":
                os.kill(os.getpid(), signal.SIGTERM)
            else:  # a stop at once the operator's signal did not ask (e.g. a wait nobody answers)
                eng.request_stop_now("the test")
            outcome = await asyncio.wait_for(run, 120)
        finally:
            operator.uninstall()
            os.close(write_end)
        assert outcome.status == "failed" and "drives not confirmed stopped" in outcome.message, outcome
        assert late_at, "the run never reported its fault"
        await wait_for(lambda: all(emergency_words_since(view, late_at[0]).values()), 30, "OFF3 at both drives")
        await wait_for(lambda: "emergency stop (OFF3) sent to both drives" in out.getvalue(), 30, "the outcome said")
        view.freeze()
    text = out.getvalue()
    assert "the run does not hold the drives (not opened yet, or let go): emergency stop (OFF3) to both" in text, text
