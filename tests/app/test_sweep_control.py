"""RunEngine control on the real simulator: confirm, pause/resume, stop, abort, interlocks."""

import asyncio
import re
import time

import h5py
import pytest

from orbitrig.errors import OrbitrigError
from orbitrig.run.engine import StatusEvent
from support.sweep_helpers import running, small_matrix, wait_for

CW_EMERGENCY = 0x047B  # spec control word (OFF3), written out on purpose

pytestmark = pytest.mark.timeout(120)


def _stored(out):
    with h5py.File(out / "run.h5", "r") as f:
        pts = {
            n: (bool(g.attrs["complete"]), {t: bool(b.attrs["complete"]) for t, b in g["frequencies"].items()})
            for n, g in f["points"].items()
        }
        return str(f.attrs["status"]), str(f.attrs["status_message"]), pts


def _spindles_stopped(sim) -> bool:
    spin, orbit = sim.speeds
    return abs(spin) < 1.0 and abs(orbit) < 1.0


async def test_confirm_pause_resume_then_stop(tmp_path):
    out = tmp_path / "run"
    async with running(tmp_path, small_matrix(), confirm_mode="remote") as (sim, eng, rec, run):
        await wait_for(lambda: eng.state == "waiting", what="waiting for the manual settings")
        assert eng.waiting_step == "manual:0000"
        assert "orbit radius 5.76 µm" in eng.message
        with pytest.raises(OrbitrigError, match="waiting for 'manual:0000'"):
            eng.confirm("manual:0001")
        assert _spindles_stopped(sim)  # nothing turns before the operator confirms
        eng.confirm("manual:0000")
        with pytest.raises(OrbitrigError, match="not waiting"):
            eng.confirm("manual:0000")
        await wait_for(lambda: rec.blocks_done() >= 2, what="two blocks")
        eng.request_pause()
        await wait_for(lambda: eng.state == "paused", what="paused")
        held = rec.blocks_done()
        await asyncio.sleep(0.5)
        assert rec.blocks_done() == held  # holds at the safe point
        assert not _spindles_stopped(sim)  # drives keep their speeds while paused
        eng.request_resume()
        await wait_for(lambda: rec.blocks_done() > held, what="resumed")
        eng.request_stop()
        outcome = await run
        assert _spindles_stopped(sim)
    assert outcome.status == "stopped"
    assert outcome.completed_points == []
    status, _, pts = _stored(out)
    assert status == "stopped"
    complete, blocks = pts["0000"]
    assert not complete  # the point was not finished: resume will redo it
    assert 3 <= len(blocks) < 10 and all(blocks.values())
    states = rec.states()
    for s in ("running", "waiting", "paused", "stopping", "idle"):
        assert s in states
    assert states[-1] == "idle"


async def test_abort_emergency_ramp_keeps_complete_data(tmp_path):
    out = tmp_path / "run"
    async with running(tmp_path, small_matrix(spin_rpm=[1000.0, 2000.0])) as (sim, eng, rec, run):
        await wait_for(lambda: rec.blocks_done() >= 3, what="three blocks")
        t_abort = time.monotonic()
        eng.request_abort()
        outcome = await run
        assert _spindles_stopped(sim)
        # the emergency stop word reached both drives on the abort itself (generous bound: a busy host)
        first = [
            min(
                (t for t, cw in sim.drive(dev)["control_words"] if t >= t_abort and cw == CW_EMERGENCY),
                default=float("inf"),
            )
            for dev in (1, 2)
        ]
        assert max(first) - t_abort < 2.0, first
    assert outcome.status == "aborted"
    log = (out / "run.log").read_text()  # sent before the run unwound, repeated by its cleanup
    assert log.index("drives: emergency stop (OFF3) sent on the abort in ") < log.index(
        "drives: emergency stop (OFF3); standstill after"
    ), log[-2000:]
    status, message, pts = _stored(out)
    assert status == "aborted" and "abort" in message
    assert list(pts) == ["0000"] and not pts["0000"][0]
    assert all(pts["0000"][1].values())  # whatever is stored is complete
    assert rec.states()[-1] == "idle"


async def test_can_heartbeat_loss_suspends_until_it_returns(tmp_path):
    out = tmp_path / "run"
    async with running(tmp_path, small_matrix(revolutions=30, spin_rpm=[1000.0, 2000.0])) as (sim, eng, rec, run):
        await wait_for(lambda: rec.blocks_done() >= 2, what="two blocks")
        sim.inject("can_heartbeat_loss", on=True)
        await wait_for(lambda: eng.state == "paused", timeout=10, what="suspension")
        assert "suspended by interlock" in eng.message and "CAN" in eng.message
        sim.inject("can_heartbeat_loss", on=False)
        outcome = await run
    assert outcome.status == "completed", outcome.message
    status, _, pts = _stored(out)
    assert status == "completed" and all(p[0] and len(p[1]) == 10 for p in pts.values()) and len(pts) == 2
    assert any("interlock cleared" in e.message for e in rec.events if isinstance(e, StatusEvent))


async def test_supply_pressure_out_of_band_suspends(tmp_path):
    out = tmp_path / "run"
    async with running(tmp_path, small_matrix(revolutions=30)) as (sim, eng, rec, run):
        await wait_for(lambda: rec.blocks_done() >= 2, what="two blocks")
        sim.set_manual(pressure_ratio=0.05)  # supply = 0.4826 / 0.05 = 9.7 MPa > 8 MPa
        await wait_for(lambda: eng.state == "paused", timeout=10, what="suspension")
        assert "supply pressure" in eng.message and "outside the band 0.2..8 MPa" in eng.message
        held = rec.blocks_done()
        await asyncio.sleep(0.3)
        assert eng.state == "paused" and rec.blocks_done() == held
        sim.set_manual(pressure_ratio=0.4)
        outcome = await run
    assert outcome.status == "completed", outcome.message
    assert _stored(out)[2]["0000"][0]


async def test_drive_trip_fails_the_run_and_stops_both_drives(tmp_path):
    out = tmp_path / "run"
    async with running(tmp_path, small_matrix()) as (sim, eng, rec, run):
        await wait_for(lambda: rec.blocks_done() >= 2, what="two blocks")
        sim.inject("drive_trip", drive=2, code=2310)
        outcome = await run
        await wait_for(lambda: _spindles_stopped(sim), timeout=10, what="spindles at rest")
    assert outcome.status == "failed"
    assert "2310" in outcome.message
    assert eng.state == "faulted"
    status, message, pts = _stored(out)
    assert status == "failed" and "2310" in message
    assert all(pts["0000"][1].values()) and not pts["0000"][0]


async def test_lost_trigger_fails_with_a_clear_message(tmp_path):
    out = tmp_path / "run"
    async with running(tmp_path, small_matrix()) as (sim, eng, rec, run):
        await wait_for(lambda: rec.blocks_done() >= 2, what="two blocks")
        sim.inject("missing_trigger", count=10**9)
        outcome = await run
        assert _spindles_stopped(sim)
    assert outcome.status == "failed"
    assert "acquisition failed" in outcome.message and "trigger" in outcome.message
    assert _stored(out)[0] == "failed"


async def test_a_drive_trip_while_waiting_for_the_operator_fails_the_run_at_once(tmp_path):
    """Interlocks are supervised in their own task: a trip ends the run even while it waits for a confirmation."""
    async with running(tmp_path, small_matrix(), confirm_mode="remote") as (sim, eng, rec, run):
        await wait_for(lambda: eng.state == "waiting", what="waiting for the manual settings")
        sim.inject("drive_trip", drive=1, code=2310)
        outcome = await asyncio.wait_for(run, 10)
    assert outcome.status == "failed" and outcome.message.startswith(
        "interlock: spin drive (id 1), register FAULT (6), fault 2310 (overcurrent): tripped"
    )
    assert eng.state == "faulted" and eng.waiting_step is None
    assert rec.states()[-2:] == ["stopping", "faulted"]  # reported once the drives are safe


async def _other_client_stops_the_orbit_drive(sim) -> None:
    from drives.link import ModbusLink

    async with ModbusLink(sim.link.call("state")["endpoints"]["modbus"], timeout=1.0) as other:
        await other.write(2, 0, [0x047E])  # OFF1 (spec control word, written out on purpose)


async def _keypads_take_both_drives(sim) -> None:
    await asyncio.to_thread(sim.link.call, "local_control", spin=50.0, orbit=30.0, hand_back=True)


@pytest.mark.parametrize(
    "act, first",
    [
        (_other_client_stops_the_orbit_drive, r"orbit drive \(id 2\), register SW \(3\): is no longer running"),
        # both drives go local at once: a poll that read the spin drive just before names the orbit drive
        (
            _keypads_take_both_drives,
            r"(spin drive \(id 1\)|orbit drive \(id 2\)), register SW \(3\): was taken to local control",
        ),
    ],
    ids=["another client", "keypads"],
)
async def test_a_drive_stopped_or_taken_elsewhere_fails_the_run_at_once(tmp_path, act, first):
    """Another Modbus client (a second terminal's `orbitrig drives stop`) stops the orbit drive, or
    the drives are taken to their keypads, mid-run: the run's drive poll finds a drive no longer
    under the run's command, stops both and fails the run at once naming the drive. The run went
    on with the spindles turning for about 10 s (another client: the acquisition's timeout, then
    the settle wait, "drives did not settle"), or 5 s at the keypads' speeds ("acquisition
    failed ... orbit trigger lost or A/D link down?"), naming neither the drive nor the cause."""
    async with running(tmp_path, small_matrix(revolutions=30)) as (sim, eng, rec, run):
        await wait_for(lambda: rec.blocks_done() >= 2, what="two blocks")
        t0 = time.monotonic()
        await act(sim)
        await wait_for(run.done, timeout=30, what="the run's end")
        ended = time.monotonic() - t0
        outcome = run.result()
        await wait_for(lambda: _spindles_stopped(sim), timeout=10, what="spindles at rest")
    assert outcome.status == "failed"
    assert re.match(f"interlock: drive poll: {first}", outcome.message), outcome.message
    assert "stopped or changed by another client, or at the drive" in outcome.message
    assert ended < 3.0, ended


async def test_a_drive_held_at_its_keypad_mid_run_fails_the_point_and_stops_the_other(tmp_path):
    """Mid-run, someone takes the spin drive to its keypad and keeps it there: it refuses the
    network's control words (docs/protocols/drive-modbus.md, "Local control"). The run fails at once
    naming the spin drive and local control, the orbit drive is stopped, the spin drive turns on at
    the keypad's speed (not said stopped), and the blocks stored before are kept."""
    out = tmp_path / "run"
    async with running(tmp_path, small_matrix(revolutions=30)) as (sim, eng, rec, run):
        await wait_for(lambda: rec.blocks_done() >= 2, what="two blocks")
        await asyncio.to_thread(sim.link.call, "keypad", drive=1, speed=50.0)
        await wait_for(run.done, timeout=30, what="the run's end")
        outcome = run.result()
        await wait_for(lambda: abs(sim.speeds[1]) < 1.0, timeout=10, what="the orbit spindle at rest")
        spin = sim.speeds[0]
        await asyncio.to_thread(sim.link.call, "keypad", drive=1, speed=None)  # the operator gives it back
    assert spin == pytest.approx(50.0, abs=0.5)  # the keypad's speed: the network did not stop it
    assert outcome.status == "failed"
    said = (
        "drives not confirmed stopped: DriveInLocalControl: spin drive (id 1), register CW (0): did not take the "
        "emergency stop (OFF3, 0x047B): in local control (status word REMOTE = 0): the operator at its keypad has it"
    )
    assert outcome.message.startswith(said), outcome.message
    assert "orbit drive (id 2), which took the stop, at standstill" in outcome.message, outcome.message
    found = "interlock: drive poll: spin drive (id 1), register SW (3): was taken to local control (SW REMOTE = 0"
    assert found in outcome.message, outcome.message
    status, _, pts = _stored(out)
    assert status == "failed"
    assert any(any(blocks.values()) for _, blocks in pts.values()), pts  # the blocks measured before: kept


async def test_a_sweep_started_with_a_drive_at_its_keypad_is_refused_before_anything_turns(tmp_path):
    """The orbit drive held at its keypad (standstill) as the sweep starts: the first point's start
    gives both drives the ready word before either gets a run word, the orbit drive refuses it, and
    the run fails naming the drive and local control; the spin drive was never run (before: it was
    run up to the point's speed, then stopped when the orbit drive refused its word)."""
    from orbitrig.cli.simulated_rig import simulated_rig
    from orbitrig.run.engine import RunEngine
    from support.rig_configs import patient_rig

    async with simulated_rig(20.0) as (sim, access):
        await asyncio.to_thread(sim.link.call, "keypad", drive=2, speed=0.0)
        eng = RunEngine(patient_rig(), out_dir=tmp_path / "run", access=access, confirm_mode="auto")
        outcome = await asyncio.wait_for(eng.run(small_matrix()), 60)
        words = (await asyncio.to_thread(sim.link.call, "drives"))["drives"]
        await asyncio.to_thread(sim.link.call, "keypad", drive=2, speed=None)
    assert outcome.status == "failed", outcome.message
    said = "orbit drive (id 2), register CW (0): did not take the ready word (0x0476): in local control"
    assert said in outcome.message, outcome.message
    assert all(cw != 0x047F for _, cw in words["1"]["control_words"]), words["1"]  # the spin drive never run
    assert words["2"]["keypad"] is True and words["1"]["rpm"] == 0.0
