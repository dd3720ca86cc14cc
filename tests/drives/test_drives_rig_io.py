"""`orbitrig.run.rig_io.RigIO` builds its RigDrives from the rig configuration's [drives]."""

from __future__ import annotations

import pytest

from orbitrig.config import load_rig
from orbitrig.cli.simulated_rig import simulated_access
from orbitrig.run.rig_io import RigIO
from sim.rig import SimRig

pytestmark = pytest.mark.timeout(30)


async def test_rig_io_passes_the_configured_drive_link_settings():
    rig = load_rig()
    d = rig.drives.model_copy(update={"link_loss_polls": 2, "timeout_s": 0.12, "poll_interval_s": 0.08})
    rig = rig.model_copy(update={"drives": d})
    async with SimRig(speedup=10) as sim:
        async with RigIO(rig, simulated_access(sim).endpoints) as io:
            drives = io.drives
            assert drives.link_loss_polls == 2  # not the RigDrives default of 3
            assert drives.link.timeout == pytest.approx(0.12)
            assert drives.poll_interval == pytest.approx(0.08)
            assert drives.limits.max_ratio == rig.drives.max_ratio
        for dev in (1, 2):  # closing RigIO sent the ramp stop (CW 0x047E), ACT 0
            cw, ref, _, _, act, _, fault = sim.drives[dev].read(0, 7)
            assert (cw, ref, act, fault) == (0x047E, 0, 0, 0)
