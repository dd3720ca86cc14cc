"""An abort that no run carries out goes to the drives of the rig configuration loaded last.

`orbitrig serve` loads rig.toml again at each start; the operator moved the drives to another
Modbus address between two runs (here: another simulator). Once that run has ended, an abort
with no run active sends the emergency stop (OFF3) to the drives at the new address, and
nothing to the old one.

Real parts: mosquitto with the shipped ACL and accounts, the service `orbitrig serve` builds
(in process, no --sim: its rig configuration names the endpoints), two simulators serving
Modbus TCP, the A/D board over TCP and CAN on a virtual bus each."""

from __future__ import annotations

import asyncio
import time

import pytest

from drives import registers as R
from orbitrig.config import load_rig
from support.mqtt_helpers import RigClient, endpoint_lines, service_in_process, wait
from support.polling import until
from support.rig_configs import lab_record_config

pytestmark = pytest.mark.timeout(240)


def off3_since(sim_rig, t0: float) -> dict[int, bool]:
    """Device id -> whether it took the emergency stop word since `t0` (monotonic s)."""
    return {
        dev: R.CW_EMERGENCY_STOP in [cw for t, cw in d.control_words if t >= t0] for dev, d in sim_rig.drives.items()
    }


async def test_an_abort_with_no_run_reaches_the_drives_of_the_reloaded_configuration(broker, tmp_path):
    from sim.rig import SimRig

    async with (
        SimRig(speedup=20.0, adc_pty=False, can_channel="reload-old") as old,
        SimRig(speedup=20.0, adc_pty=False, can_channel="reload-new") as new,
    ):
        config = lab_record_config(tmp_path / "lab", edits=endpoint_lines(old))
        svc = service_in_process(
            broker.url, tmp_path, "moved-rig", rig=load_rig(config), abort=False, reload=config, reconnect_initial=0.2
        )
        shutdown = asyncio.Event()
        task = asyncio.create_task(svc.serve(shutdown))
        rc = RigClient(broker, "moved-rig")
        try:
            await wait(rc.status, "idle")
            # between runs the operator moves the drives to another address (rig.toml edited)
            config.write_text(lab_record_config(tmp_path / "lab2", edits=endpoint_lines(new)).read_text())
            mark = rc.watch.mark()
            assert (await wait(rc.command, {"cmd": "start", "matrix": "quick"}))["ok"] is True
            assert (await wait(rc.command, {"cmd": "stop"}))["ok"] is True
            await until(lambda: svc._run_task is not None and not svc.run_active, 120, "the run's end")
            await wait(rc.status, lambda s: s["state"] in ("idle", "faulted") and s["run_id"], 30, mark)

            for rig in (old, new):  # someone at the drives of both rigs, no run
                rig.local_control(spin=50.0, orbit=-30.0, hand_back=True)
            await until(lambda: min(abs(w) for w in old.speeds + new.speeds) > 10.0, 30, "all drives turning")
            t_abort = time.monotonic()
            reply = await wait(rc.command, {"cmd": "abort"})
            assert reply["ok"] is True and "emergency stop (OFF3) sent to both drives" in reply["detail"], reply
            assert off3_since(new, t_abort) == {1: True, 2: True}  # the drives rig.toml names now
            assert off3_since(old, t_abort) == {1: False, 2: False}  # not those it named at the service's start
        finally:
            rc.close()
            shutdown.set()
            await asyncio.wait_for(asyncio.gather(task, return_exceptions=True), 120)
