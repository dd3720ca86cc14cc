"""The terminal operator of `orbitrig sweep` while a manual setting waits for its confirmation:
real SIGINTs to this process reach its handlers; a second one always aborts (an "r" answered in
between does not make it a first one again), and the simulator's drives get the emergency stop."""

import asyncio
import io
import os
import signal
import sys

import pytest
from rich.console import Console

from orbitrig.cli.operator import Operator
from support.sweep_helpers import running, small_matrix, wait_for

pytestmark = pytest.mark.timeout(60)
CW_EMERGENCY = 0x047B  # spec control word, written out on purpose


@pytest.mark.parametrize("between", [None, "r"], ids=["twice", "resume-answered-between"])
async def test_a_second_ctrl_c_while_confirming_aborts(tmp_path, monkeypatch, between):
    read_end, write_end = os.pipe()  # the operator's terminal: open, nothing typed
    monkeypatch.setattr(sys, "stdin", os.fdopen(read_end))
    async with running(tmp_path, small_matrix(), confirm_mode="prompt") as (sim, eng, rec, run):
        out = io.StringIO()
        operator = Operator(eng, Console(file=out, width=200))
        eng.subscribe(operator.on_event)
        operator.install()
        try:
            await wait_for(lambda: eng.state == "waiting", what="waiting for the manual settings")
            os.kill(os.getpid(), signal.SIGINT)
            await wait_for(lambda: "[r]esume, [s]top, [a]bort" in out.getvalue(), what="the pause prompt")
            # the pause cannot hold the run before the setting is confirmed: the question says so
            said = " ".join(out.getvalue().split())
            assert "pause requested: the run pauses once manual:0000 is confirmed" in said, said
            assert "paused at the next safe point" not in said
            if between is not None:
                operator._choice(between)  # the operator's typed answer
                await wait_for(
                    lambda: "press Enter to confirm" in out.getvalue().split("[a]bort")[-1],
                    what="the confirmation asked again",
                )
                await asyncio.sleep(0.2)
                assert out.getvalue().split("[a]bort")[-1].count("press Enter to confirm") == 1  # asked once
            assert eng.state == "waiting" and not run.done()
            os.kill(os.getpid(), signal.SIGINT)
            outcome = await asyncio.wait_for(run, 20)
        finally:
            operator.uninstall()
            os.close(write_end)
    assert outcome.status == "aborted", outcome.message
    assert "Ctrl-C; a second signal: aborting" in out.getvalue()
    assert sim.drive(1)["control_word"] == sim.drive(2)["control_word"] == CW_EMERGENCY


async def test_a_first_signal_while_the_run_stops_itself_aborts_and_is_not_said_to_be_a_second(tmp_path, monkeypatch):
    """A stop under way that no signal asked (the operator's "stop"): the first SIGTERM aborts it (exit 4
    in `orbitrig sweep`), said as 'SIGTERM while stopping' and recorded as SIGTERM alone (before, the
    terminal said 'SIGTERM again' of the only signal)."""
    read_end, write_end = os.pipe()
    monkeypatch.setattr(sys, "stdin", os.fdopen(read_end))
    async with running(tmp_path, small_matrix(), speedup=1.0) as (sim, eng, rec, run):
        out = io.StringIO()
        operator = Operator(eng, Console(file=out, width=200))
        eng.subscribe(operator.on_event)
        operator.install()
        try:
            await wait_for(lambda: sim.speeds[0] > 500 * 2 * 3.14159 / 60, timeout=30, what="spin turning")
            eng.request_stop(by="ada")
            await wait_for(lambda: eng.state == "stopping", what="the stop")
            os.kill(os.getpid(), signal.SIGTERM)
            outcome = await asyncio.wait_for(run, 20)
        finally:
            operator.uninstall()
            os.close(write_end)
    assert outcome.status == "aborted" and outcome.message.startswith("aborted by unnamed (SIGTERM);"), outcome.message
    assert "SIGTERM while stopping: aborting" in out.getvalue(), out.getvalue()
    assert "second signal" not in out.getvalue() + outcome.message and "again" not in out.getvalue()
    log = (tmp_path / "run" / "run.log").read_text()
    assert "abort requested by unnamed (SIGTERM)" in log and "second signal" not in log, log


@pytest.mark.parametrize("second", [False, True], ids=["let-the-ramp-end", "ctrl-c-again"])
async def test_ctrl_c_in_the_closing_ramp_offers_no_pause(tmp_path, monkeypatch, second):
    """Ctrl-C once every point is measured, both drives ramping to zero at the end: nothing is left to
    pause, so the terminal says what is happening and asks stop / abort (before, it asked resume / stop
    / abort after 'pause requested: the run pauses at its next safe point'). Nothing answered, the run
    completes; a second Ctrl-C aborts (the emergency stop), 'all points completed; ' ahead of who asked."""
    from orbitrig.run.control import CLOSING_RAMP, NOTHING_TO_PAUSE
    from orbitrig.run.engine import StatusEvent

    read_end, write_end = os.pipe()
    monkeypatch.setattr(sys, "stdin", os.fdopen(read_end))
    async with running(tmp_path, small_matrix(revolutions=6, spin_rpm=[1000.0]), speedup=8.0) as (sim, eng, rec, run):
        out = io.StringIO()
        operator = Operator(eng, Console(file=out, width=300))
        eng.subscribe(operator.on_event)
        loop, sent = asyncio.get_running_loop(), []

        def at_the_ramp(ev) -> None:
            if isinstance(ev, StatusEvent) and not sent and ev.message.endswith(CLOSING_RAMP):
                sent.append(ev.state)
                loop.call_soon(os.kill, os.getpid(), signal.SIGINT)

        eng.subscribe(at_the_ramp)
        operator.install()
        try:
            await wait_for(lambda: "[a]bort" in out.getvalue(), timeout=30, what="the question Ctrl-C asks")
            if second:
                os.kill(os.getpid(), signal.SIGINT)
            outcome = await asyncio.wait_for(run, 30)
        finally:
            operator.uninstall()
            os.close(write_end)
    said = " ".join(out.getvalue().split())
    assert sent == ["running"], sent
    assert f"Ctrl-C: {NOTHING_TO_PAUSE}" in said, said
    assert "[s]top, [a]bort (emergency stop), Enter: let the run complete? (Ctrl-C again aborts)" in said, said
    assert "[r]esume" not in said and "pause requested" not in said and "paused" not in said, said
    log = (tmp_path / "run" / "run.log").read_text()
    assert "pause requested" not in log and "paused" not in log, log
    if second:
        assert outcome.status == "aborted", outcome.message
        assert outcome.message.startswith("all points completed; aborted by unnamed (Ctrl-C; a second signal)"), outcome
        assert "emergency stop (OFF3)" in log and "Ctrl-C; a second signal: aborting" in said, said
    else:
        assert (outcome.status, outcome.message) == ("completed", "all points completed"), outcome
    assert outcome.completed_points == [0] and sim.speeds == (0.0, 0.0)


@pytest.mark.parametrize("stdin", ["open", "closed"])
async def test_ctrl_c_during_the_last_points_identification_offers_no_pause(tmp_path, monkeypatch, stdin):
    """Ctrl-C once the last point is past its last safe point (the one before its identification):
    no safe point follows, so no pause could ever hold the run (before, 'pause requested: the run
    pauses at its next safe point', and the run completed without pausing, the question left
    unanswered). The run refuses the pause (one rule with the service's reply), the terminal says why
    and asks stop / abort; nothing answered, the run completes, no pause in run.log. Standard input
    closed (nobody can answer): nothing holds the run, which completes too (before: 'nobody can
    answer: stopping the run', a run with every point measured ended stopped, exit 3). The real
    identification runs; the signal is sent as it starts, the question printed before it goes on."""
    from orbitrig.run.control import NOTHING_TO_PAUSE
    from orbitrig.run.point_record import PointRecord

    read_end, write_end = os.pipe()
    monkeypatch.setattr(sys, "stdin", os.fdopen(read_end))
    if stdin == "closed":
        os.close(write_end)
    out = io.StringIO()
    identify, asked = PointRecord.identify, []

    async def ctrl_c_first(self, step, ps):
        asked.append(ps.point.index)
        os.kill(os.getpid(), signal.SIGINT)
        await wait_for(lambda: "[a]bort" in out.getvalue(), timeout=30, what="the question Ctrl-C asks")
        await identify(self, step, ps)

    monkeypatch.setattr(PointRecord, "identify", ctrl_c_first)
    async with running(tmp_path, small_matrix(revolutions=6, spin_rpm=[1000.0]), speedup=8.0) as (sim, eng, rec, run):
        operator = Operator(eng, Console(file=out, width=300))
        eng.subscribe(operator.on_event)
        operator.install()
        try:
            outcome = await asyncio.wait_for(run, 30)
        finally:
            operator.uninstall()
            if stdin == "open":
                os.close(write_end)
    said = " ".join(out.getvalue().split())
    assert asked == [0], asked  # the one point is the last
    closed = "standard input is closed, nobody can answer: the run completes (Ctrl-C again aborts)"
    assert (closed in said) == (stdin == "closed") and "stopping the run" not in said, said
    assert f"Ctrl-C: {NOTHING_TO_PAUSE}" in said, said
    assert "[s]top, [a]bort (emergency stop), Enter: let the run complete?" in said, said
    assert "pause requested" not in said and "[r]esume" not in said, said
    log = (tmp_path / "run" / "run.log").read_text()
    assert "pause requested" not in log and "paused" not in log, log
    assert (outcome.status, outcome.message, outcome.completed_points) == ("completed", "all points completed", [0])
    assert sim.speeds == (0.0, 0.0)
