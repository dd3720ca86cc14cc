"""An abort that arrives as the run's opening of the rig has ended, before the run has resumed from
it, is the run's to carry out: its stop words go out at once over the run's own link.

The run took up its open rig a loop step after the opening ended; an abort in between found no
rig (`RunEngine.request_abort` False: "nothing reached the drives through the run"), so whoever
aborted sent the emergency stop over a link of its own, which on RTU (one program holds the port)
could not be opened while the run held it: the rig service waited for the run to let go of it
(at most 5 s, then answering "emergency stop NOT sent"), while the run's drives were open and polled. Now the abort's
emergency stop goes out on the run's link at once, request_abort says so, and run.log has it.

Real parts: the simulator in process, its drives over Modbus RTU on a pty (a serial port opened
exclusively), turned from their keypads before the run. The abort is asked the moment the opening
has ended (a loop step a real operator cannot be made to hit)."""

import asyncio
import dataclasses
import time

import pytest

from orbitrig.cli.simulated_rig import simulated_access
from orbitrig.config import load_rig
from orbitrig.run.engine import RunEngine
from orbitrig.run.rig_io import RigIO
from support.sweep_helpers import small_matrix, wait_for

pytestmark = pytest.mark.timeout(120)

CW_EMERGENCY = 0x047B  # the spec's emergency stop word, written out here (not imported from drives/)
COMM_LOSS_TIMEOUT = 104  # the spec's register, in 0.1 s


async def test_an_abort_as_the_rig_has_opened_is_sent_by_the_run(tmp_path, monkeypatch):
    from sim.rig import SimRig

    rig = load_rig()
    async with SimRig(speedup=20, adc_pty=False, modbus_rtu_pty=True) as sim_rig:
        url = f"rtu://{sim_rig.modbus_rtu_path}"
        sim_access = simulated_access(sim_rig)
        access = dataclasses.replace(sim_access, endpoints=dataclasses.replace(sim_access.endpoints, modbus_url=url))
        for drive in sim_rig.drives.values():  # the watchdog the run configures: nothing to write on entry
            drive.write(COMM_LOSS_TIMEOUT, [round(rig.drives.comm_loss_timeout_s / 0.1)])
        sim_rig.local_control(spin=100.0, orbit=-30.0, hand_back=True)  # turned from the keypads, no run
        await wait_for(lambda: min(abs(w) for w in sim_rig.speeds) > 10.0, 30, what="both drives turning")
        engine = RunEngine(rig, out_dir=tmp_path / "run", access=access, confirm_mode="auto")
        real_enter = RigIO.__aenter__
        asked: list[tuple[float, bool]] = []

        def abort() -> None:
            asked.append((time.monotonic(), engine.request_abort(by="ada")))

        async def enter(self):
            opened = await real_enter(self)
            asyncio.get_running_loop().call_soon(abort)  # before the run resumes from the opening
            return opened

        monkeypatch.setattr(RigIO, "__aenter__", enter)
        outcome = await asyncio.wait_for(engine.run(small_matrix()), 60)
        assert outcome.status == "aborted", outcome.message
        ((t_abort, carried),) = asked
        assert carried is True  # the run holds the drives: its stop words went out
        for device, drive in sim_rig.drives.items():
            off3 = [t - t_abort for t, cw in drive.control_words if t >= t_abort and cw == CW_EMERGENCY]
            assert off3 and off3[0] < 0.5, (device, off3)
        log = (tmp_path / "run" / "run.log").read_text()
        assert "drives: emergency stop (OFF3) sent on the abort in" in log, log
