"""A signal, an MQTT stop or abort that arrives while a run ends, every point measured and stored and
both drives ramping down at the end, does what it says, as the MQTT contract has it: a stop at once
ramps the drives and ends the run stopped, an abort turns the ramp into the emergency stop and ends
it aborted (run.h5, the catalog, the service's closing status, the sweep's exit 3 or 4). Its end
message starts with 'all points completed; ' and has no 'incomplete' note: nobody looks for points
that are not missing.

Real parts: the simulator in its own process, the engine over Modbus TCP, run.h5 read back as the
catalog reads it."""

from __future__ import annotations

import asyncio

import pytest

from orbitrig.catalog.rows import run_rows
from orbitrig.cli.sweep import EXIT
from orbitrig.run.control import CLOSING_RAMP
from orbitrig.run.ending import closing_why
from orbitrig.run.engine import StatusEvent
from orbitrig.run.states import STOPPING
from orbitrig.store.reader import read_run
from support.sweep_helpers import running, small_matrix

pytestmark = pytest.mark.timeout(120)


def _asks(eng, request: str):
    """The request a signal, or an MQTT command, makes of the engine."""
    return {
        "SIGTERM": lambda: eng.request_stop_now("SIGTERM", by="ada"),
        "MQTT stop": lambda: eng.request_stop(by="ada"),
        "MQTT abort": lambda: eng.request_abort(by="ada"),
        "Ctrl-C while stopping": lambda: eng.request_abort(by="ada", why="Ctrl-C"),
    }[request]


#: what each request ends the run as (status, sweep's exit status, end message)
ENDS = {
    "SIGTERM": ("stopped", 3, "all points completed; stopped at once by SIGTERM"),
    "MQTT stop": ("stopped", 3, "all points completed; stopped by ada"),
    "MQTT abort": ("aborted", 4, "all points completed; aborted by ada"),
    "Ctrl-C while stopping": ("aborted", 4, "all points completed; aborted by ada (Ctrl-C) while stopping"),
}


def _when(request: str):
    """The status the request is sent at: the closing ramp's start (running), or the run's end
    under way (stopping: a signal then aborts, as `orbitrig sweep` and `orbitrig serve` do)."""
    if request == "Ctrl-C while stopping":
        return lambda ev: ev.state == STOPPING
    return lambda ev: ev.message == CLOSING_RAMP


@pytest.mark.parametrize("request_", list(ENDS))
async def test_a_request_in_the_closing_ramp_ends_the_run_as_it_says_all_points_completed(tmp_path, request_):
    status, code, message = ENDS[request_]
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
    assert (outcome.status, outcome.message) == (status, message)
    assert EXIT[outcome.status] == code  # `orbitrig sweep`'s exit status
    assert outcome.completed_points == [0] and outcome.points == 1
    # the service's closing status: 'run stopped: all points completed; stopped by ada'
    assert f"run {outcome.status}{closing_why(outcome.status, outcome.message)}" == f"run {status}: {message}"
    stored = read_run(tmp_path / "run")
    assert (str(stored.status), stored.status_message) == (status, message)
    assert {r["run_status"] for r in run_rows(stored)} == {status}
    text = (tmp_path / "run" / "run.log").read_text()
    assert f"ended: {status}: {message}\n" in text, text  # the whole message: no 'incomplete' note
    assert "standstill after" in text and "spin ACT 0 rpm, fault 0; orbit ACT 0 rpm, fault 0" in text, text
    if status == "aborted":  # the abort turned the closing ramp into the emergency stop
        assert "emergency stop (OFF3)" in text, text
