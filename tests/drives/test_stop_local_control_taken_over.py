"""A stop taken over by a later one (drives/stop.py StopSender) leaves the status read that says a
refusing drive is in local control (drives/local_control.py) to that later stop: the emergency stop
asked while a ramp stop's words go out reaches the drives before any read. On the simulator's
drives over real Modbus (TCP, RTU on a pty); the spin drive is held at its keypad (it refuses every
control word with exception 03), the requests are read from the drive models."""

from __future__ import annotations

import asyncio

import pytest
from support.drives_testkit import CW_EMERGENCY, CW_RAMP_STOP, CW_RUN, SimDrives

from drives.drive import Drive
from drives.errors import DriveExceptionResponse
from drives.link import ModbusLink
from drives.local_control import DriveInLocalControl
from drives.pair import drive_names
from drives.stop import StopSender, send_stop

pytestmark = pytest.mark.timeout(60)

CW, REF, SW = 0, 1, 3  # register addresses
CW_READY = 0x0476


async def test_an_emergency_stop_asked_during_a_refused_ramp_stop_goes_out_before_any_status_read(
    sim: SimDrives, monkeypatch
) -> None:
    """Spin drive at its keypad, orbit drive running. The emergency stop is asked the moment the
    orbit drive takes the ramp stop: its words and zero references go out before any status word is
    read (before: the ramp stop read the spin drive's status word first, the emergency stop waiting
    for it), and the emergency stop, not the one it took over, says the spin drive is in local
    control (before: the ramp stop said its refused OFF1 was the emergency stop word refused)."""
    sim.models[2].write(CW, [CW_RUN])
    sim.models[1].local_control(50.0)
    link = ModbusLink(sim.url, timeout=0.25, names=drive_names(1, 2))
    await link.connect()
    drives = [Drive(link, 1, "spin", bidirectional=False), Drive(link, 2, "orbit", bidirectional=True)]
    stops = StopSender(drives)
    seen: list[tuple[str, int, int, int]] = []  # (request, device id, address, first value)
    emergency: list[asyncio.Task] = []

    def spy(dev: int) -> None:
        model = sim.models[dev]
        read, write = model.read, model.write

        def reading(address, count):
            seen.append(("read", dev, address, count))
            return read(address, count)

        def writing(address, values):
            seen.append(("write", dev, address, values[0]))
            if (dev, address, values[0]) == (2, CW, CW_RAMP_STOP) and not emergency:
                emergency.append(stops.send(emergency=True))  # asked as the orbit drive takes OFF1
            write(address, values)

        monkeypatch.setattr(model, "read", reading)
        monkeypatch.setattr(model, "write", writing)

    spy(1), spy(2)
    try:
        async with link:
            ramp = stops.send()
            ramp_errors = await ramp
            assert emergency, seen
            emergency_errors = await emergency[0]
    finally:
        sim.models[1].hand_back()
    cw_writes = [i for i, r in enumerate(seen) if r[0] == "write" and r[2] == CW]
    reads = [i for i, r in enumerate(seen) if r[:3] == ("read", 1, SW)]  # not a write's own read-back
    assert len(reads) == 1 and reads[0] > cw_writes[-1], seen  # both stops' words first, one read after
    assert [e.drive for e in ramp_errors] == [1], ramp_errors
    assert not isinstance(ramp_errors[0], DriveInLocalControl), ramp_errors  # never "did not take OFF3"
    assert "emergency stop" not in str(ramp_errors[0]), ramp_errors
    assert [e.drive for e in emergency_errors] == [1], emergency_errors
    assert isinstance(emergency_errors[0], DriveInLocalControl), emergency_errors
    assert "emergency stop (OFF3, 0x047B)" in str(emergency_errors[0])
    assert sim.regs(2)["CW"] == CW_EMERGENCY and sim.regs(2)["REF"] == 0


async def test_a_status_read_that_raises_the_unforeseen_leaves_the_stops_errors_said(
    sim: SimDrives, monkeypatch, caplog
) -> None:
    """The read after a refused stop word raises what no link error is (a mock: the fault of a
    client library no real drive makes): the stop still returns the refusing drive's exception
    answer, logged, the orbit drive's words taken (before: the stop raised the RuntimeError, its
    errors and its log lost)."""
    sim.models[2].write(CW, [CW_RUN])
    sim.models[1].local_control(50.0)
    try:
        async with ModbusLink(sim.url, timeout=0.25, names=drive_names(1, 2)) as link:
            real = link.read

            async def read(device_id, address, count, **kw):
                if address == SW:
                    raise RuntimeError("a client library's own fault")
                return await real(device_id, address, count, **kw)

            monkeypatch.setattr(link, "read", read)
            drives = [Drive(link, 1, "spin", bidirectional=False), Drive(link, 2, "orbit", bidirectional=True)]
            errors = await send_stop(drives, emergency=True)
    finally:
        sim.models[1].hand_back()
    assert [e.drive for e in errors] == [1] and isinstance(errors[0], DriveExceptionResponse), errors
    assert errors[0].exception_code == 3, errors
    assert any("stop command not delivered: spin drive (id 1)" in r.getMessage() for r in caplog.records)
    assert sim.regs(2)["CW"] == CW_EMERGENCY and sim.regs(2)["REF"] == 0


async def test_a_starts_status_read_after_a_refused_ready_word_waits_for_the_stop(sim: SimDrives, monkeypatch) -> None:
    """An abort asked as the spin drive (at its keypad) is sent a start's ready word: the start's
    status read that says local control goes out once the stop's words and zero references have,
    never between them (before: read as a stop's own, it went between the spin drive's OFF3 and the
    orbit drive's)."""
    sim.models[2].write(CW, [CW_RUN])
    sim.models[1].local_control(50.0)
    link = ModbusLink(sim.url, timeout=0.25, names=drive_names(1, 2))
    await link.connect()
    drives = [Drive(link, 1, "spin", bidirectional=False), Drive(link, 2, "orbit", bidirectional=True)]
    stops = StopSender(drives)
    seen: list[tuple[str, int, int, int]] = []
    abort: list[asyncio.Task] = []
    for dev in (1, 2):
        model = sim.models[dev]

        def reading(address, count, dev=dev, read=model.read):
            seen.append(("read", dev, address, count))
            return read(address, count)

        def writing(address, values, dev=dev, write=model.write):
            seen.append(("write", dev, address, values[0]))
            if (dev, address, values[0]) == (1, CW, CW_READY) and not abort:
                abort.append(stops.send(emergency=True))  # asked as the ready word is on the link
            write(address, values)

        monkeypatch.setattr(model, "read", reading)
        monkeypatch.setattr(model, "write", writing)
    try:
        async with link:
            with pytest.raises(DriveInLocalControl, match=r"did not take the ready word \(0x0476\)"):
                await drives[0].ready()
            assert abort, seen
            await abort[0]
    finally:
        sim.models[1].hand_back()
    stop_words = [i for i, r in enumerate(seen) if r[0] == "write" and r[3] != CW_READY]
    first_read = next(i for i, r in enumerate(seen) if r[:3] == ("read", 1, SW))
    assert [seen[i][1:] for i in stop_words] == [(1, CW, CW_EMERGENCY), (2, CW, CW_EMERGENCY), (1, REF, 0), (2, REF, 0)]
    assert first_read > stop_words[-1], seen  # OFF3 to both, zero REFs, then the read
