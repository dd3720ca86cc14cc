"""`orbitrig drives stop` interrupted while it opens the drives: the stop words still go out to
each drive that answers, and the message names those that took theirs (never "both" falsely).

RTU on a pty: a drive id nobody answers (--orbit-id 3) makes the opening wait out its reads, so
a signal lands there (the request for id 3 is watched at the server). The drives' watchdog is
switched off, so only a stop word the command delivers can stop them.
"""

from __future__ import annotations

import asyncio
import signal
import tempfile
import time
from pathlib import Path

import pytest
from drives.limits import DriveLimits
from drives.link import ModbusLink
from orbitrig.config import default_rig_path
from support.cli_helpers import orbitrig_started_async, reaped_async
from support.drives_testkit import (
    CW_EMERGENCY,
    CW_RAMP_STOP,
    CW_RUN,
    PARAM,
    RPM,
    SPEEDUP,
    SimDrives,
    make_models,
    open_rig,
    serve,
    set_parameter,
)

pytestmark = pytest.mark.timeout(60)  # a hang fails fast, with a traceback

SILENT_ID = 3  # no drive answers this id on the RTU line


@pytest.fixture
async def rtu_sim(request) -> SimDrives:
    """The drives on RTU, ramps sped up `request.param` times (default SPEEDUP; 2: a stop takes about 1 s)."""
    models = make_models(speedup=getattr(request, "param", SPEEDUP))
    endpoint = await serve("rtu", models)
    try:
        yield SimDrives("rtu", models, endpoint)
    finally:
        await endpoint.aclose()


async def _leave_running(sim: SimDrives) -> None:
    """Both drives left turning by a client gone away, their comm-loss watchdog off."""
    rig = open_rig(sim, DriveLimits(2400 * RPM, 2400 * RPM), comm_loss_timeout=0.0, timeout=1.0)  # nothing unanswered
    async with rig:
        await rig.set_speeds(1200 * RPM, 600 * RPM)
        await rig.wait_settled(hold=0.1, timeout=20)
        rig.release()
    assert sim.regs(1)["CW"] == CW_RUN and sim.regs(1)["ACT"] > 0


def _watch_silent_id(sim: SimDrives, monkeypatch) -> list[asyncio.Event]:
    """Events set at the 1st, 2nd, ... request the server sees for SILENT_ID (it stays unanswered)."""
    gate = sim.endpoint._gate  # the server's request filter (RTU): no public hook sees each request
    admit = gate.admit
    events = [asyncio.Event() for _ in range(8)]
    seen = 0

    def spy(dev_id: int) -> bool:
        nonlocal seen
        if dev_id == SILENT_ID and seen < len(events):
            events[seen].set()
            seen += 1
        return admit(dev_id)

    monkeypatch.setattr(gate, "admit", spy)
    return events


#: each request the silent drive leaves unanswered is waited out, retried once, for each word of the
#: stop (a dozen requests): the lab's patient 1 s per request made that some 20 s; 0.3 s is still
#: twice the shipped rig's 0.15 s (config/rig.toml), the margin of a loaded machine
REQUEST_TIMEOUT_S = 0.3


def _quicker_config(folder: Path) -> Path:
    """The tests' lab rig.toml (the patient link) with a Modbus request timeout of REQUEST_TIMEOUT_S."""
    text = default_rig_path().read_text()
    assert "timeout_s = 1.0" in text
    path = folder / "rig.toml"
    path.write_text(text.replace("timeout_s = 1.0", f"timeout_s = {REQUEST_TIMEOUT_S}", 1))
    return path


async def _stop_cli(sim: SimDrives, args: list[str], moments) -> tuple[int, str]:
    """`drives stop --modbus URL --config RIG *args` (RIG: `_quicker_config`), SIGINT after each awaited
    ``moments()``; (exit code, stderr)."""
    with tempfile.TemporaryDirectory() as folder:
        config = _quicker_config(Path(folder))
        return await _stop_cli_with(sim, ["--config", str(config), *args], moments)


async def _stop_cli_with(sim: SimDrives, args: list[str], moments) -> tuple[int, str]:
    proc = await orbitrig_started_async("drives", "stop", "--modbus", sim.url, *args)
    async with reaped_async(proc):
        for moment in moments:
            await moment()
            proc.send_signal(signal.SIGINT)
        _, err = await asyncio.wait_for(proc.communicate(), 30)
    assert proc.returncode is not None
    return proc.returncode, err.decode()


async def _stop_with_signals(sim: SimDrives, signal_at: list[asyncio.Event]) -> tuple[int, str]:
    """`drives stop --orbit-id 3`, SIGINT at each of `signal_at`; (exit code, stderr)."""
    return await _stop_cli(
        sim, ["--orbit-id", str(SILENT_ID)], [lambda e=e: asyncio.wait_for(e.wait(), 20) for e in signal_at]
    )


async def _assert_spin_stopped_orbit_untouched(sim: SimDrives) -> None:
    assert sim.regs(1)["CW"] == CW_RAMP_STOP, sim.regs(1)
    await sim.wait_for(lambda: sim.regs(1)["ACT"] == 0, 5, "spin standstill")
    assert sim.regs(2)["CW"] == CW_RUN and sim.regs(2)["ACT"] != 0  # id 2 was not addressed


async def test_sigint_while_opening_still_stops_the_drive_that_answers(rtu_sim, monkeypatch):
    sim = rtu_sim
    await _leave_running(sim)
    asked = _watch_silent_id(sim, monkeypatch)
    code, err = await _stop_with_signals(sim, [asked[0]])  # while reading drive 3's parameters
    assert code == 2, err
    line = (
        "interrupted by SIGINT while opening the drives; ramp stop (OFF1, orbit (id 3) not read) sent; "
        "stop word delivered to: spin (id 1)\n"
    )
    assert f"orbitrig drives stop: {line}" in err, err
    assert "both" not in err, err
    # the read to drive 3 left on the line fails as it closes: no traceback for it on the terminal
    assert "Traceback" not in err and "never retrieved" not in err, err
    await _assert_spin_stopped_orbit_untouched(sim)


async def test_second_sigint_during_the_stop_words_makes_them_the_emergency_stop_claiming_nothing_false(
    rtu_sim, monkeypatch
):
    """A second signal while the stop words go out (drive 3 unanswered): the words become the
    emergency stop (OFF3), as a second signal does in every other stop of `drives`; the drive that
    took the ramp stop gets OFF3 next; exit 4, naming only the drive that took it."""
    sim = rtu_sim
    await _leave_running(sim)
    asked = _watch_silent_id(sim, monkeypatch)
    # 1st: drive 3's parameter read (opening); 2nd: its stop word (the best-effort sending)
    code, err = await _stop_with_signals(sim, [asked[0], asked[1]])
    assert code == 4, err
    line = (
        "while opening the drives; SIGINT during the ramp stop: emergency stop (OFF3) sent; "
        "stop word delivered to: spin (id 1)\n"
    )
    assert line in err, err
    assert "both" not in err and "Traceback" not in err, err
    assert sim.regs(1)["CW"] == CW_EMERGENCY, sim.regs(1)
    await sim.wait_for(lambda: sim.regs(1)["ACT"] == 0, 5, "spin standstill")
    assert sim.regs(2)["CW"] == CW_RUN and sim.regs(2)["ACT"] != 0  # id 2 was not addressed


async def _stop_interrupted_while_ramping(sim: SimDrives, before_signal=lambda: None) -> tuple[int, str, float]:
    """`drives stop`, SIGINT once both stop words are out and the drives still ramp (the rig
    open); ``before_signal()`` just before it; (exit code, stderr, wall s from the signal to the exit)."""
    t_signal = 0.0

    async def ramping() -> None:
        nonlocal t_signal
        await sim.wait_for(lambda: sim.regs(1)["CW"] == sim.regs(2)["CW"] == CW_RAMP_STOP, 20, "stop words")
        assert sim.regs(1)["ACT"] != 0 and sim.regs(2)["ACT"] != 0  # still ramping: the command waits for standstill
        before_signal()
        t_signal = time.monotonic()

    code, err = await _stop_cli(sim, [], [ramping])
    return code, err, time.monotonic() - t_signal


@pytest.mark.parametrize("rtu_sim", [2.0], ids=["slow"], indirect=True)
async def test_sigint_during_the_ramp_stop_makes_it_an_emergency_stop_waited_for(rtu_sim):
    """A signal while `stop` waits for the ramp to standstill (the rig open, its stop words out):
    both drives get the emergency stop (OFF3), the command waits for standstill, says so, exit 4.
    (It used to exit 2 at once, the drives still ramping, and a second Ctrl-C found no command.)"""
    sim = rtu_sim
    await _leave_running(sim)
    code, err, took = await _stop_interrupted_while_ramping(sim)
    at_exit = [sim.regs(dev) for dev in (1, 2)]
    assert code == 4, (err, at_exit, took)
    for regs in at_exit:  # read as the command exited: stopped by the emergency stop
        assert regs["CW"] == CW_EMERGENCY and regs["ACT"] == 0, at_exit
    line = "orbitrig drives stop: SIGINT during the ramp stop: emergency stop (OFF3) sent; both drives stopped; "
    assert line + "drives: emergency stop (OFF3) after an abort during the ramp; standstill after " in err, err
    assert "Traceback" not in err, err
    assert took < 8.0, took  # the emergency ramp (about 0.1 s here) and the exit, with a busy machine's margin


@pytest.mark.parametrize("rtu_sim", [2.0], ids=["slow"], indirect=True)
async def test_sigint_during_the_ramp_stop_says_which_drive_missed_the_emergency_stop(rtu_sim, monkeypatch):
    """A signal while `stop` waits for standstill, the orbit drive gone silent after its ramp stop
    word: the emergency stop reaches the spin drive only; the message says so (never "both"), exit 2."""
    sim = rtu_sim
    await _leave_running(sim)
    gate = sim.endpoint._gate  # the server's request filter: the orbit drive's line cut
    admit, silent = gate.admit, asyncio.Event()
    monkeypatch.setattr(gate, "admit", lambda dev_id: not (silent.is_set() and dev_id == 2) and admit(dev_id))
    code, err, _ = await _stop_interrupted_while_ramping(sim, silent.set)
    assert code == 2, err
    assert "orbitrig drives stop: error (" in err and "orbit" in err, err
    assert "SIGINT during the ramp stop: emergency stop (OFF3) sent; stop word delivered to: spin (id 1)\n" in err, err
    assert "both drives stopped" not in err and "Traceback" not in err, err
    assert sim.regs(1)["CW"] == CW_EMERGENCY and sim.regs(2)["CW"] == CW_RAMP_STOP


@pytest.mark.parametrize("rtu_sim", [2.0], ids=["slow"], indirect=True)
async def test_the_stop_words_after_a_failed_opening_keep_another_clients_emergency_stop(rtu_sim):
    """`drives stop` that cannot open the drives (drive 3 silent) sends its stop words over the
    bare link: the spin drive, in the emergency ramp another client's OFF3 started, is read there
    first and gets the emergency stop (OFF3), never the ramp stop (OFF1) that would turn that ramp
    into the ten times slower ramp stop; the message says why, and that drive 3 was not read.
    (DECEL_TIME 1000 s for 3000 rpm, at 2 x: the emergency ramp 60 rpm per wall s, about 20 s from
    1200 rpm, long enough for the command on a loaded machine; the ramp stop 6 rpm per s.)"""
    sim = rtu_sim
    set_parameter(sim.models[1], PARAM["DECEL_TIME"], 10000)
    await _leave_running(sim)
    async with ModbusLink(sim.url, timeout=0.3) as other:  # another client's emergency stop
        t_off3 = time.monotonic()
        await other.write(1, 0, [CW_EMERGENCY])
    await sim.wait_for(lambda: sim.rpm(1) < 1180, 5, "the spin drive's emergency ramp")
    code, err = await _stop_cli(sim, ["--orbit-id", str(SILENT_ID)], [])
    words = [cw for t, cw in sim.models[1].control_words if t > t_off3]
    assert CW_RAMP_STOP not in words and CW_EMERGENCY in words, ([hex(w) for w in words], err)
    before, t_before = sim.rpm(1), time.monotonic()
    assert before > 0, err  # still along the emergency ramp as the command ended
    await asyncio.sleep(1.0)
    slowed = (before - sim.rpm(1)) / (time.monotonic() - t_before)
    assert 40 < slowed < 80, slowed  # rpm per wall s: the emergency ramp's 60, not the ramp stop's 6
    assert code == 2, err
    line = (
        "emergency stop (OFF3, as spin (id 1) read turning in its emergency ramp; orbit (id 3) not read) sent; "
        "stop word delivered to: spin (id 1)\n"
    )
    assert "orbitrig drives stop: error (" in err and line in err, err
