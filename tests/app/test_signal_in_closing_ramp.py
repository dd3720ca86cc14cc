"""A signal (or an MQTT stop) that arrives while a run ends, every point measured and stored and
both drives ramping down at the end, keeps its meaning for the drives (a stop at once ramps them,
an abort turns the ramp into the emergency stop), but the run ends completed: its data are
complete. Before, it ended stopped or aborted, and an operator took points for missing.

Real parts: the simulator in its own process, the engine over Modbus TCP, run.h5 read back as the
catalog reads it."""

from __future__ import annotations

import asyncio

import pytest

from orbitrig.catalog.rows import run_rows
from orbitrig.run.ending import closing_why
from orbitrig.run.engine import StatusEvent
from orbitrig.run.states import STOPPING
from orbitrig.store.reader import read_run
from support.sweep_helpers import running, small_matrix

pytestmark = pytest.mark.timeout(120)

#: the status the run says as its closing ramp starts (orbitrig.run.engine)
LAST_RAMP = "every point measured: both drives ramp to zero"


def _asks(eng, request: str):
    """The request a signal, or the MQTT stop, makes of the engine."""
    return {
        "SIGTERM": lambda: eng.request_stop_now("SIGTERM", by="ada"),
        "MQTT stop": lambda: eng.request_stop(by="ada"),
        "Ctrl-C while stopping": lambda: eng.request_abort(by="ada", why="Ctrl-C"),
    }[request]


def _when(request: str):
    """The status the request is sent at: the closing ramp's start (running), or the run's end
    under way (stopping: a signal then aborts, as `orbitrig sweep` and `orbitrig serve` do)."""
    if request == "Ctrl-C while stopping":
        return lambda ev: ev.state == STOPPING
    return lambda ev: ev.message == LAST_RAMP


@pytest.mark.parametrize("request_", ["SIGTERM", "MQTT stop", "Ctrl-C while stopping"])
async def test_a_signal_in_the_closing_ramp_leaves_the_run_completed(tmp_path, request_):
    matrix = small_matrix(revolutions=6, spin_rpm=[1000.0])
    async with running(tmp_path, matrix) as (sim, eng, rec, run):
        sent: list[str] = []
        loop, ask, when = asyncio.get_running_loop(), _asks(eng, request_), _when(request_)

        def on_status(ev) -> None:
            if isinstance(ev, StatusEvent) and not sent and when(ev):
                sent.append(ev.message)
                loop.call_soon(ask)  # as a signal handler or the MQTT client does: from the loop

        eng.subscribe(on_status)
        outcome = await asyncio.wait_for(run, 90)
        speeds = sim.speeds
    assert sent, "the request was never sent"
    assert speeds == (0.0, 0.0)
    assert outcome.status == "completed", outcome.message
    assert outcome.completed_points == [0] and outcome.points == 1
    assert outcome.message.startswith("all points completed; "), outcome.message
    # the service's closing status says who asked: 'run completed: all points completed; stopped by ada'
    assert closing_why(outcome.status, outcome.message) == f": {outcome.message}"
    stored = read_run(tmp_path / "run")
    assert str(stored.status) == "completed"
    assert {r["run_status"] for r in run_rows(stored)} == {"completed"}
    text = (tmp_path / "run" / "run.log").read_text()
    assert "ended: completed: all points completed; " in text, text
    assert "standstill after" in text and "spin ACT 0 rpm, fault 0; orbit ACT 0 rpm, fault 0" in text, text
    if request_ == "Ctrl-C while stopping":  # the abort keeps its meaning for the drives
        assert "aborted by ada (Ctrl-C)" in outcome.message, outcome.message
