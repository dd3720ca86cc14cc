"""A calibration step interrupted while its session opens the rig: the drives' entry lets go of
their link at once when cancelled (drives/entry.py: whoever cancelled it stops the drives over a
link of its own), so drives found turning there, or not read yet, are not left to run on. The
ramp stop words (OFF1) go to each drive that answers, over a link of the session's own; a second
signal meanwhile makes them the emergency stop (OFF3); the session's note names the drives that
took theirs, then the step ends interrupted, as `orbitrig calibrate` runs it (`run_until_signal`,
a real SIGINT to this process). A drive that does not take its word fails the step ("drives not
confirmed stopped"): nothing may say the drives were stopped.

The simulator in this process (Modbus TCP, and RTU on a pty: the entry has let go of the port
for the session's own link), its drives left turning with their comm-loss watchdog off (only a
stop word delivered stops them); the orbit drive's requests go unanswered while the entry reads
it, so the signal lands there (each request for it is watched at the server's request filter)."""

from __future__ import annotations

import dataclasses
import os
import signal
import time

import pytest

from drives import registers as R
from drives.limits import DriveLimits
from drives.link import ModbusLink
from drives.rig import RigDrives
from orbitrig.cli.signals import Interrupted, run_until_signal
from orbitrig.cli.simulated_rig import simulated_access
from orbitrig.config import RPM, load_rig
from orbitrig.run.calibration import CalibrationSession
from orbitrig.run.calibration_checks import CalibrationFailed

pytestmark = pytest.mark.timeout(90)
CW_RUN, CW_RAMP_STOP, CW_EMERGENCY = 0x047F, 0x047E, 0x047B


async def _left_running(url: str) -> None:
    """Both drives left turning by a client gone away, their comm-loss watchdog off."""
    limits = DriveLimits(2400 * RPM, 2400 * RPM)  # 1 s a request: no answer is meant to be missed here
    async with RigDrives(url, limits, poll_interval=0.05, timeout=1.0, comm_loss_timeout=0.0) as rig:
        await rig.set_speeds(600 * RPM, 300 * RPM)
        await rig.wait_settled(hold=0.1, timeout=20)
        rig.release()


def _orbit_silent(endpoint, monkeypatch, signals: int, gone: bool) -> None:
    """From now on the orbit drive's (id 2) first request (the entry's read of its parameters)
    and, with `signals` 2, its second (its ramp stop word) go unanswered, each with a SIGINT to
    this process; it answers the ones after, unless `gone`."""
    gate = endpoint._gate  # the server's request filter: no public hook sees each request
    admit, state = gate.admit, {"asked": 0}

    def spy(dev_id: int) -> bool:
        if dev_id == 2 and state["asked"] < signals:
            state["asked"] += 1
            os.kill(os.getpid(), signal.SIGINT)  # handled by the loop once this request's turn ends
            return False
        return not (gone and dev_id == 2) and admit(dev_id)

    monkeypatch.setattr(gate, "admit", spy)


async def _spin_in_its_emergency_ramp(url: str) -> None:
    """Another client's emergency stop (OFF3) to the spin drive."""
    async with ModbusLink(url, timeout=0.3) as other:
        await other.write(1, R.CW, [CW_EMERGENCY])


def _step(monkeypatch, signals: int, seen: dict, gone: bool = False, kind: str = "tcp", off3: bool = False):
    async def step() -> None:
        from sim.rig import SimRig

        async with SimRig(speedup=20.0, adc_pty=False, modbus_rtu_pty=kind == "rtu") as sim_rig:
            endpoint = sim_rig.modbus_servers[kind == "rtu"]
            drives = sim_rig.drives
            if off3:  # DECEL_TIME 1800 s for 3000 rpm: at 20 x from 600 rpm the emergency ramp 1.8 s wall
                drives[1].write(R.DECEL_TIME, [18000])
            await _left_running(endpoint.url)
            assert all(d.read(0, 1)[0] == CW_RUN for d in drives.values())
            if off3:
                await _spin_in_its_emergency_ramp(endpoint.url)
            t0 = time.monotonic()
            _orbit_silent(endpoint, monkeypatch, signals, gone)
            access = simulated_access(sim_rig)
            access = dataclasses.replace(
                access, endpoints=dataclasses.replace(access.endpoints, modbus_url=endpoint.url)
            )
            try:
                async with CalibrationSession(load_rig(), access, seen["notes"].append):
                    seen["opened"] = True
            finally:
                seen["words"] = {dev: {cw for t, cw in d.control_words if t >= t0} for dev, d in drives.items()}
                seen["regs"] = {dev: d.read(0, 2) for dev, d in drives.items()}

    return step


@pytest.mark.parametrize("kind", ["tcp", "rtu"])
@pytest.mark.parametrize(
    ("signals", "word", "said"),
    [
        (1, CW_RAMP_STOP, "ramp stop (OFF1) sent"),
        (2, CW_EMERGENCY, "interrupted again during the ramp stop: emergency stop (OFF3) sent"),
    ],
)
def test_a_signal_while_the_session_opens_stops_the_drives_found_turning(monkeypatch, kind, signals, word, said):
    seen: dict = {"notes": []}
    with pytest.raises(Interrupted) as stopped:
        run_until_signal(_step(monkeypatch, signals, seen, kind=kind), "calibrate")
    assert stopped.value.sig == signal.SIGINT and "opened" not in seen
    for dev in (1, 2):
        cw, ref = seen["regs"][dev]
        assert cw == word and ref == 0, (dev, hex(cw), ref, seen)
        assert CW_RUN not in seen["words"][dev], seen["words"]
    line = f"interrupted while opening the rig; {said}; stop word delivered to: spin (id 1), orbit (id 2)"
    assert line in seen["notes"], seen["notes"]


@pytest.mark.parametrize("kind", ["tcp", "rtu"])
def test_the_stop_words_keep_an_emergency_ramp_another_client_started(monkeypatch, kind):
    """The spin drive in the emergency ramp of another client's OFF3 as the session opens: the
    session's stop words read it there first and are the emergency stop (OFF3), never the ramp
    stop (OFF1) that would turn that ramp into the ten times slower one; the note says why."""
    seen: dict = {"notes": []}
    with pytest.raises(Interrupted):
        run_until_signal(_step(monkeypatch, 1, seen, kind=kind, off3=True), "calibrate")
    for dev in (1, 2):
        assert CW_RAMP_STOP not in seen["words"][dev] and CW_EMERGENCY in seen["words"][dev], seen["words"]
        assert seen["regs"][dev][0] == CW_EMERGENCY, seen
    said = "emergency stop (OFF3, as spin (id 1) read turning in its emergency ramp) sent"
    line = f"interrupted while opening the rig; {said}; stop word delivered to: spin (id 1), orbit (id 2)"
    assert line in seen["notes"], seen["notes"]


def test_a_drive_that_does_not_take_its_stop_word_fails_the_step(monkeypatch):
    seen: dict = {"notes": []}
    with pytest.raises(CalibrationFailed) as failed:
        run_until_signal(_step(monkeypatch, 1, seen, gone=True), "calibrate")
    said = str(failed.value)
    assert said.startswith(
        "interrupted while opening the rig; ramp stop (OFF1, orbit (id 2) not read) sent; "
        "stop word delivered to: spin (id 1); "
        "drives not confirmed stopped: DriveTimeoutError: orbit drive (id 2), register CW (0): no answer"
    ), said
    assert seen["regs"][1] == [CW_RAMP_STOP, 0] and seen["regs"][2][0] == CW_RUN, seen
    assert seen["notes"] == [], seen["notes"]


def test_the_command_says_no_more_of_the_drives_than_the_note_before_it(monkeypatch, capsys):
    """`orbitrig calibrate`'s last line after a signal while the rig opens: the session's note
    said which drives took the ramp stop word (no standstill was waited for); the last line says
    the step stopped and that no record was written, nothing more of the drives (exit 3)."""
    import typer

    from orbitrig.cli.calibrate import _guarded

    seen: dict = {"notes": []}
    with pytest.raises(typer.Exit) as ended:
        _guarded(lambda: run_until_signal(_step(monkeypatch, 1, seen), "calibrate"))
    assert ended.value.exit_code == 3
    assert any("stop word delivered to: spin (id 1), orbit (id 2)" in n for n in seen["notes"]), seen["notes"]
    err = capsys.readouterr().err
    assert err.splitlines()[-1] == "calibration stopped by Ctrl-C: no record written", err
    assert "stopped, no record" not in err and "drives were stopped" not in err, err
