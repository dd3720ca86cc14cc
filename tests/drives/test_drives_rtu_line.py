"""The RTU line against the simulator's RTU server on a pty: every request
answered exactly once and in order, under load, and stale frames discarded."""

from __future__ import annotations

import asyncio
import os
import time

import pytest
from support.drives_testkit import make_models, serve

from drives.link import ModbusLink
from drives.rtu import RtuGarbled, RtuLine, crc16, frame, inter_frame_silence, next_frame

pytestmark = pytest.mark.timeout(60)

REF2 = 2  # read/write scratch register of the spec: reads back what was written


async def _busy_loop(stop: asyncio.Event) -> None:
    """Load on the shared event loop: 0.5 ms of CPU between yields."""
    while not stop.is_set():
        t = time.perf_counter()
        while time.perf_counter() - t < 0.0005:
            pass
        await asyncio.sleep(0)


async def test_rtu_hammer_zero_missing_or_mismatched_answers():
    models = make_models()
    endpoint = await serve("rtu", models)
    stop = asyncio.Event()
    load = [asyncio.create_task(_busy_loop(stop))]
    # 1 s a request: a late answer is not a lost one. With both cores busy the pty's bytes and this
    # loop (client and server in one) stalled an answer past 0.3 s with nothing lost (server: all answered).
    link = ModbusLink(endpoint.url, timeout=1.0)
    n, wrong, t0 = 150, [], time.perf_counter()
    try:
        await link.connect()

        async def heartbeat():  # a second task on the same link, like the poll
            while not stop.is_set():
                for dev in (1, 2):
                    assert len(await link.read(dev, 0, 7)) == 7
                await asyncio.sleep(0.02)

        poll = asyncio.create_task(heartbeat())
        for i in range(n):
            dev, value = 1 + i % 2, (i * 7919) & 0xFFFF
            await link.write(dev, REF2, [value])  # FC06
            got = await link.read(dev, REF2, 1)
            if got != [value] or models[dev].read(REF2, 1) != [value]:
                wrong.append((i, dev, value, got))
            await link.write(dev, 0, [0x0476, 0])  # FC16 (CW, REF): ready, zero reference
        stop.set()
        await poll
    finally:
        stop.set()
        for t in load:
            await t
        await link.close()
        await endpoint.aclose()
    rate = link.requests / (time.perf_counter() - t0)
    line_stats = (link.failures, wrong)
    assert line_stats == (0, []), f"{link.failures} failed requests, mismatched: {wrong[:5]}"
    assert link.requests >= 3 * n
    assert endpoint._server.requests == endpoint._server.answered == link.requests
    print(f"RTU: {link.requests} requests at {rate:.0f}/s under load, 0 lost, 0 mismatched")


def test_next_frame_hunts_past_noise_and_fragments():
    a = frame(1, bytes([3, 2, 0x12, 0x34]))
    b = frame(2, bytes([6, 0, 2, 0xAB, 0xCD]))
    assert next_frame(a) == (0, len(a))
    assert next_frame(a[:-1]) is None
    assert next_frame(b"\x55\x01" + a) == (2, 2 + len(a))  # noise first
    assert next_frame(a[:5] + b) == (5, 5 + len(b))  # a broken frame does not hide the next
    assert crc16(b"\x01\x03\x00\x00\x00\x07") == 0x0804  # sent 04 08
    assert inter_frame_silence(19200) == pytest.approx(3.5 * 11 / 19200)
    assert inter_frame_silence(115200) == 1.75e-3


async def _fake_drive(master: int, answers: list[bytes], done: asyncio.Event) -> None:
    """A raw device on the pty master: to each request, writes the next canned bytes."""
    loop = asyncio.get_running_loop()
    buf = bytearray()

    def readable():
        buf.extend(os.read(master, 256))
        while next_frame_request(buf):
            if answers:
                os.write(master, answers.pop(0))
            if not answers:
                done.set()

    loop.add_reader(master, readable)


def next_frame_request(buf: bytearray) -> bool:
    if len(buf) >= 8:
        del buf[:8]  # FC03 / FC06 requests are 8 bytes
        return True
    return False


async def test_stale_and_foreign_frames_are_discarded():
    from sim.pty import close_fds, open_raw_pty

    master, slave, path = open_raw_pty()
    loop = asyncio.get_running_loop()
    good = frame(1, bytes([3, 2, 0x00, 0x2A]))
    answers = [
        frame(2, bytes([3, 2, 0, 9])) + b"\x00" + good,  # another drive's frame + noise, then ours
        frame(1, bytes([3, 4, 0, 1, 0, 2])) + frame(1, bytes([6, 0, 2, 0, 5])),  # wrong shape/FC
    ]
    done = asyncio.Event()
    await _fake_drive(master, answers, done)
    line = RtuLine(path, baud=19200, timeout=0.2)
    try:
        await line.connect()
        rsp = await line.read_holding_registers(2, count=1, device_id=1)
        assert rsp.registers == [42] and line.discarded_frames == 1
        with pytest.raises(asyncio.TimeoutError):  # neither frame is the answer: wait on
            await line.read_holding_registers(2, count=1, device_id=1)
        assert line.discarded_frames == 3
    finally:
        line.close()
        loop.remove_reader(master)
        close_fds(master, slave)


async def test_a_late_answer_is_not_taken_for_the_next_one():
    """The device answers request 1 after the client gave up; request 2 (same
    device, function and size) must get its own answer, not the late one."""
    from sim.pty import close_fds, open_raw_pty

    master, slave, path = open_raw_pty()
    loop = asyncio.get_running_loop()
    buf, seen = bytearray(), []

    def readable():
        buf.extend(os.read(master, 256))
        while len(buf) >= 8:
            del buf[:8]
            seen.append(loop.time())
            if len(seen) == 1:  # 0.15 s late: after the 0.1 s timeout, well within the settle time
                loop.call_later(0.15, os.write, master, frame(1, bytes([3, 2, 0, 111])))
            else:
                os.write(master, frame(1, bytes([3, 2, 0, 222])))

    loop.add_reader(master, readable)
    # settle 0.3 s: the late answer lands 0.15 s into the 0.4 s it covers, with room for a loop
    # (the device's and the client's, one here) held up for a while with both cores busy
    line = RtuLine(path, baud=19200, timeout=0.1, settle=0.3)
    try:
        await line.connect()
        with pytest.raises(asyncio.TimeoutError):
            await line.read_holding_registers(2, count=1, device_id=1)
        rsp = await line.read_holding_registers(2, count=1, device_id=1)
        assert rsp.registers == [222]
        assert line.discarded_frames == 1  # the late 111, dropped while nothing was awaited
        assert seen[1] - seen[0] >= 0.15 + line.settle - 0.01  # request 2 waited for quiet
    finally:
        line.close()
        loop.remove_reader(master)
        close_fds(master, slave)


async def test_a_drive_that_always_answers_late_is_not_called_a_wrong_baud_rate():
    """Every answer 0.15 s after its request, the timeout 0.1 s: the second request's failure
    counts the first's late answer, a valid frame, so it names a late drive (or another master),
    not a wrong baud rate or another device's stream, as bytes without a valid frame would be."""
    from sim.pty import close_fds, open_raw_pty

    master, slave, path = open_raw_pty()
    loop = asyncio.get_running_loop()
    buf, late = bytearray(), []

    def readable():
        buf.extend(os.read(master, 256))
        while len(buf) >= 8:
            del buf[:8]
            late.append(loop.call_later(0.15, os.write, master, frame(1, bytes([3, 2, 0, 111]))))

    loop.add_reader(master, readable)
    line = RtuLine(path, baud=19200, timeout=0.1, settle=0.3)  # settle: as in the test above
    try:
        await line.connect()
        with pytest.raises(asyncio.TimeoutError) as first:
            await line.read_holding_registers(2, count=1, device_id=1)
        assert not isinstance(first.value, RtuGarbled)  # nothing came while it waited
        with pytest.raises(RtuGarbled) as second:
            await line.read_holding_registers(2, count=1, device_id=1)
        said = str(second.value)
        assert said.startswith(
            f"7 byte(s) came on {path}, 1 valid RTU frame(s) among them, none this request's answer: a drive answering later than the timeout"
        ), said
        assert "baud" not in said
    finally:
        for answer in late:
            answer.cancel()
        line.close()
        loop.remove_reader(master)
        close_fds(master, slave)


async def test_a_line_that_fails_its_setup_after_opening_is_closed_and_reported_as_a_link_error(monkeypatch):
    """The port opened (exclusive) and then its terminal setup failed (termios.error, as when a
    USB adapter goes away between the two): the failure is an OSError, the link error every
    caller handles, and the port is closed, so the next connect can open it again."""
    import termios

    from drives import rtu
    from sim.pty import close_fds, open_raw_pty

    master, slave, path = open_raw_pty()
    line = RtuLine(path, baud=19200, timeout=0.2)
    real = termios.tcgetattr

    class _GoneAway:  # the module's termios with a setup that fails: what the real pty cannot do
        error = termios.error

        def __getattr__(self, name):
            return getattr(termios, name)

        @staticmethod
        def tcgetattr(fd):
            raise termios.error(5, "Input/output error")

    try:
        monkeypatch.setattr(rtu, "termios", _GoneAway())
        with pytest.raises(OSError, match=f"cannot set up {path}: .*Input/output error"):
            await line.connect()
        assert not line.connected
        monkeypatch.setattr(rtu, "termios", termios)
        assert real is termios.tcgetattr and await line.connect()  # the exclusive lock was released
        assert line.connected
    finally:
        line.close()
        close_fds(master, slave)
