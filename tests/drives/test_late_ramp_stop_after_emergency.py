"""A ramp stop word (OFF1) the link gave up on reaches the spin drive after the abort's emergency
stop (OFF3). The contract says nothing of OFF1 after OFF3; a drive may take it as the ramp stop and
turn its emergency ramp into the ten times slower one. Real parts: the simulator's drives set to do
so (`DriveModel.off1_yields`), behind a real TCP proxy (support.modbus_proxy) that holds the spin
drive's first ramp stop word past the request timeout and delivers it right after the spin drive's
emergency stop word. Before the mend the drive ramped down at the ramp stop rate: the abort's
wait for standstill took 10.0 s instead of 1.0 s; now the poll reads the ramp stop word back in
CW with the drive turning, writes the emergency stop again (warned, the late word named), and the
drive is at standstill within its emergency ramp's time."""

from __future__ import annotations

import logging
import time

import pytest
from support.drives_testkit import CW_EMERGENCY, CW_RAMP_STOP, RPM, SPEEDUP, make_models, serve
from support.modbus_proxy import HoldingProxy, first_write, write_of

from drives import registers as R
from drives.limits import DriveLimits
from drives.rig import RigDrives
from sim.drive_states import OFF1_ACTIVE, OFF3_ACTIVE, settle

pytestmark = pytest.mark.timeout(30)

LIMITS = DriveLimits(max_spin=2400 * RPM, max_orbit=2400 * RPM, min_ratio=None, max_ratio=1.0)
TIMEOUT = 0.5  # s a request: the ramp stop word is given up after it, and may arrive for 1.0 s more
DECEL = 500.0  # s DECEL_TIME (simulated, 0 .. 3000 rpm): from 1500 rpm the ramp stop takes 10 s wall,
EMERGENCY_S = DECEL * 0.5 / SPEEDUP / 10  # the emergency ramp 1.0 s wall


async def test_a_late_ramp_stop_word_does_not_slow_the_emergency_stop(caplog):
    """Before the mend: the abort's stop took 10.0 s (the spin drive at the OFF1 rate)."""
    models = make_models()
    models[1].off1_yields = True
    endpoint = await serve("tcp", models)
    proxy = HoldingProxy(endpoint.port, first_write(1, R.CW, CW_RAMP_STOP))
    url = await proxy.start()
    try:
        async with RigDrives(
            url, LIMITS, poll_interval=0.05, timeout=TIMEOUT, comm_loss_timeout=3.0, accel_time=5.0, decel_time=DECEL
        ) as r:
            await r.set_speeds(1500 * RPM, 300 * RPM)
            await r.wait_settled(hold=0.05, timeout=5)
            await r.stop(wait=False)  # the spin word given up after 0.5 s, its retry taken: ramping slowly
            assert proxy.held and r.link.late.open([1])
            words_before = len(models[1].control_words)
            proxy.release_after(0.0, lambda frame: write_of(frame) == (1, R.CW, CW_EMERGENCY))
            t0 = time.monotonic()
            with caplog.at_level(logging.WARNING, logger="drives.poll"):
                await r.stop(emergency=True, wait=True)  # the abort's: the late OFF1 lands after its OFF3
            took = time.monotonic() - t0
            assert proxy.released.is_set()
    finally:
        await proxy.aclose()
        await endpoint.aclose()
    assert took < 1.5 * EMERGENCY_S + 0.5, took  # the emergency ramp's time, not the ramp stop's (10 s)
    spin = [cw for _, cw in models[1].control_words][words_before:]
    first = spin.index(CW_EMERGENCY)
    assert spin[first + 1] == CW_RAMP_STOP and CW_EMERGENCY in spin[first + 2 :], [hex(cw) for cw in spin]
    said = [rec.getMessage() for rec in caplog.records if "after the emergency stop" in rec.getMessage()]
    assert said and said[0].startswith("spin drive (id 1): CW (0) reads the ramp stop word 0x047E, ACT "), said
    assert "most likely our own ramp stop word given up unanswered at " in said[0], said
    assert "(CW (0) = 0x047E) reached it late" in said[0] and "emergency stop (OFF3) is written again" in said[0]


def test_the_simulated_drive_takes_a_ramp_stop_word_in_its_emergency_ramp_only_when_set_to():
    """sim/drive_states.settle: OFF3 ACTIVE runs on unless `off1_yields` (then OFF1 ACTIVE)."""
    assert settle(OFF3_ACTIVE, CW_RAMP_STOP, 900.0) == OFF3_ACTIVE
    assert settle(OFF3_ACTIVE, CW_RAMP_STOP, 900.0, off1_yields=True) == OFF1_ACTIVE
    assert settle(OFF3_ACTIVE, CW_EMERGENCY, 900.0, off1_yields=True) == OFF3_ACTIVE
    assert settle(OFF3_ACTIVE, 0x047F, 900.0, off1_yields=True) == OFF3_ACTIVE  # a run word: still not
