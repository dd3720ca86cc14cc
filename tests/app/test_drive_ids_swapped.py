"""The operator's first rig.toml with the two drives' device ids swapped (spin_id = 2, orbit_id = 1):
the drives have no identity register, each reads as commanded, so only the timing disk can tell.
Every revolution then comes at the spin's set speed, not the block's orbit speed: the run fails
with both drives stopped first, the failure naming the speed measured and the two ids to check,
not "orbit trigger lost or A/D link down?"."""

import asyncio
import re

import pytest

from orbitrig import config as cfg
from orbitrig.run.adc_link import orbit_off_hint
from rigunits import RPM
from support.sweep_helpers import first_stop, running, small_matrix

pytestmark = pytest.mark.timeout(120)

STOP_WORDS = (0x047E, 0x047B)  # spec control words (OFF1, OFF3), written out on purpose
SAID = re.compile(
    r"point 0000 \[04_fwd\]: acquisition failed \(DaqTimeoutError: .*; the timing disk measured the orbit at "
    r"([\d.]+) rpm, the block's \|Omega\| is 1200.0 rpm\); the orbit spindle turns at the spin's set speed "
    r"\(1000 rpm\): are the drives' device ids swapped \(\[drives\] spin_id = 2, orbit_id = 1 in rig.toml\)\?"
)


async def test_swapped_device_ids_fail_the_run_naming_the_ids(tmp_path):
    base = cfg.load_rig()
    swapped = base.drives.model_copy(update={"spin_id": 2, "orbit_id": 1})
    rig = base.model_copy(update={"drives": swapped})
    async with running(tmp_path, small_matrix(revolutions=20), rig) as (sim, eng, rec, run):
        outcome = await asyncio.wait_for(asyncio.shield(run), 90)
        drives = sim.drive(1), sim.drive(2)
        stopped = first_stop(sim, 0.0, STOP_WORDS)
    assert outcome.status == "failed", outcome.message
    said = SAID.search(outcome.message)
    assert said, outcome.message
    assert float(said[1]) == pytest.approx(1000.0, rel=0.01)  # the spin's 1000 rpm, on the orbit's disk
    assert "orbit trigger lost" not in outcome.message
    assert stopped is not None and [d["rpm"] for d in drives] == [0, 0]
    assert not list((tmp_path / "run" / "points" / "0000").glob("*_???.h5"))


def test_an_orbit_off_its_speed_elsewhere_names_the_orbit_id():
    spin, orbit = 1000 * RPM, 1200 * RPM
    assert orbit_off_hint(None, spin, orbit, 1, 2) == ""
    assert "swapped" in orbit_off_hint(1009 * RPM, spin, -orbit, 2, 1)  # within 1 %: the spin's speed
    other = orbit_off_hint(700 * RPM, spin, orbit, 1, 2)
    assert other == (
        "; the orbit spindle is not at the speed its drive was given: is [drives] spin_id = 1, "
        "orbit_id = 2 in rig.toml the orbit drive's id?"
    )
    assert "swapped" not in orbit_off_hint(1011 * RPM, spin, orbit, 1, 2)


@pytest.mark.parametrize("ratio", [1.012, 0.985, -1.015])
def test_an_orbit_lagging_near_the_spin_speed_is_no_swap(ratio):
    """A plan's ratio just outside the refused 0.99..1.01 (warned, run): an orbit drive short of its
    speed turns within 1 % of the spin's, so the timing disk cannot tell a swap from a lag there."""
    spin = 1000 * RPM
    said = orbit_off_hint(1001 * RPM, spin, ratio * spin, 1, 2)
    assert said.startswith("; the orbit spindle is not at the speed its drive was given"), said
