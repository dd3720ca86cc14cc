"""A drive (or its gateway) that answers the stop word with a Modbus exception that says
"not now" (06 busy, 0A gateway path unavailable, 0B gateway target did not respond) is sent
it again, like after a timeout (drives/stop.py PASSING_EXCEPTIONS); other exception answers
are not retried. On the simulator's drives over real Modbus (TCP, RTU on a pty); the
exception answers are made by the test (the simulator's drives are never busy)."""

from __future__ import annotations

import pytest
from support.drives_testkit import CW_EMERGENCY, CW_RUN, RPM, SimDrives, open_rig

from drives.drive import Drive
from drives.errors import DriveError, DriveExceptionResponse
from drives.limits import DriveLimits
from drives.link import ModbusLink
from drives.pair import drive_names
from drives.stop import send_stop
from sim.drive_registers import DriveModbusException

pytestmark = pytest.mark.timeout(60)

CW = 0  # register address


def refuse_control_words(sim: SimDrives, dev: int, code: int, times: int, monkeypatch) -> list[int]:
    """The next `times` CW writes to drive `dev` are answered with Modbus exception `code`;
    returns the CW values of every CW write it received from now on (refused or taken)."""
    model, received = sim.models[dev], []
    real = model.write

    def write(address, values):
        if address == CW:
            received.append(values[0])
            if len(received) <= times:
                raise DriveModbusException(code, "refused by the test")
        real(address, values)

    monkeypatch.setattr(model, "write", write)
    return received


@pytest.fixture(autouse=True)
def _running(sim: SimDrives) -> None:
    for dev in (1, 2):
        sim.models[dev].write(CW, [CW_RUN])


async def _stop(sim: SimDrives) -> list:
    async with ModbusLink(sim.url, timeout=0.15, names=drive_names(1, 2)) as link:
        drives = [Drive(link, 1, "spin", bidirectional=False), Drive(link, 2, "orbit", bidirectional=True)]
        return await send_stop(drives, emergency=True)


@pytest.mark.parametrize("code", [0x06, 0x0A, 0x0B])
async def test_stop_word_refused_once_with_a_passing_exception_is_sent_again(sim, code, monkeypatch):
    received = refuse_control_words(sim, 1, code, 1, monkeypatch)
    errors = await _stop(sim)
    spin = sim.regs(1)
    assert spin["CW"] == CW_EMERGENCY, (
        f"after one exception {code:02X} answer the spin drive still holds CW {spin['CW']:#06x} (REF {spin['REF']}): "
        f"CW writes received {[hex(v) for v in received]}, stop errors {[str(e) for e in errors]}"
    )
    assert received == [CW_EMERGENCY, CW_EMERGENCY] and errors == []
    assert sim.regs(2)["CW"] == CW_EMERGENCY


async def test_stop_word_a_drive_keeps_refusing_as_busy_is_tried_write_retries_times_more(sim, monkeypatch):
    """The spin drive stays busy (06): 1 + write_retries (2) tries, then its error is reported;
    the orbit drive answers 04 (device failure), which is not retried."""
    spin = refuse_control_words(sim, 1, 0x06, 99, monkeypatch)
    orbit = refuse_control_words(sim, 2, 0x04, 99, monkeypatch)
    errors = await _stop(sim)
    assert len(spin) == 3, f"the busy spin drive got {len(spin)} tries of its stop word, not 1 + 2 retries"
    assert len(orbit) == 1, f"the orbit drive's device failure (04) was retried: {len(orbit)} tries"
    assert [(e.drive, e.exception_code) for e in errors if isinstance(e, DriveExceptionResponse)] == [(1, 6), (2, 4)]


async def test_a_drive_refusing_every_stop_word_with_03_still_takes_its_zero_reference_and_is_owed(sim, monkeypatch):
    """The spin drive answers every control word with 03 (illegal value; not retried) while
    running under RigDrives: the stop raises naming it, its zero reference still brings it to
    standstill (REF 0 is taken), the orbit drive stops on its word, and the poll keeps sending
    the owed stop while the spin drive reads operation enabled, raised by `check`."""
    async with open_rig(sim, DriveLimits(max_spin=2400 * RPM, max_orbit=2400 * RPM), comm_loss_timeout=5.0) as rig:
        await rig.set_speeds(1000 * RPM, -500 * RPM)
        await rig.wait_settled(hold=0.05, timeout=10.0)
        received = refuse_control_words(sim, 1, 0x03, 10**6, monkeypatch)
        with pytest.raises(DriveExceptionResponse, match=r"spin drive \(id 1\), register CW"):
            await rig.stop(wait=False)
        assert received == [0x047E]  # one try: 03 is not retried
        assert sim.regs(1)["REF"] == 0 and sim.regs(2)["CW"] == 0x047E
        await sim.wait_stopped(timeout=5.0)  # the spin drive along its ramp to REF 0
        await sim.wait_for(lambda: len(received) >= 3, 2.0, "the owed stop sent again")
        with pytest.raises(DriveError, match="while no speed is commanded: the ramp stop"):
            rig.check()
        monkeypatch.undo()  # the spin drive takes control words again: the exit's stop reaches it
