"""AdcReader against the simulator over a real pty and over TCP: clean and with
every fault the simulator's A/D board and link can inject."""

from __future__ import annotations

import asyncio
import math
import os

import numpy as np
import pytest
from support.daq_oracle import WireTap

from daq.adc import AdcReader
from daq.errors import DaqLinkError, DaqTimeoutError
from sim.rig import SimRig

SPIN = 2 * math.pi * 30.0  # rad/s
ORBIT = 2 * math.pi * 12.5  # rad/s, forward
SPEEDUP = 20.0  # 250 revolutions per wall second
N = 50
SETTLE = 0.05  # s wall: the spindles jump to speed at the next simulator tick (10 ms)

pytestmark = pytest.mark.timeout(60)


@pytest.fixture
async def rig():
    async with SimRig(speedup=SPEEDUP, can_channel=None) as r:
        r.local_control(spin=SPIN, orbit=ORBIT)
        await asyncio.sleep(SETTLE)
        yield r


def url_of(rig, link: str) -> str:
    return rig.adc_url if link == "tcp" else rig.adc_pty_path


def slot_major(counts: np.ndarray, mode: str) -> np.ndarray:
    c = counts.shape[0]
    if mode == "simultaneous":
        return counts.T
    out = np.empty((360, 1), counts.dtype)
    for k in range(c):
        out[k::c, 0] = counts[k]
    return out


def check_block(rig, block, used, tap, *, spin=SPIN, orbit=ORBIT, mode="sequential"):
    """Fundamentals match the simulator's truth within the statistical band of the
    block's own records, and every revolution used went out intact."""
    assert block.n_revolutions == N == len(used)
    truth = np.array(list(rig.true_phasors(spin, orbit).values()))
    rec = block.record_phasors
    np.testing.assert_allclose(rec.mean(axis=0), block.phasors, rtol=1e-9, atol=1e-15)
    sigma = np.sqrt(np.mean(np.abs(rec - rec.mean(axis=0)) ** 2, axis=0) / N)
    err = np.abs(block.phasors - truth)
    assert np.all(err < 5 * sigma + 1e-3 * np.abs(truth)), (err / sigma, err / np.abs(truth))
    assert block.orbit_speed == pytest.approx(abs(orbit), rel=2e-3)
    intact = tap.intact_revolutions()
    for r in used:
        assert any(np.array_equal(slot_major(r.counts, mode), s) for s in intact.get(r.rev, [])), r.rev


async def acquire_with_fault(rig, url, fault=None, *, at=10, mode="sequential", **kw):
    """Acquire N revolutions; inject ``fault`` (a name, or a callable) once ``at`` of
    them have been used."""
    used = []
    cfg = rig.config.adc

    def hook(r):
        used.append(r)
        if fault is not None and len(used) == at:
            fault() if callable(fault) else rig.inject(fault, **kw)

    async with AdcReader(
        url, channels=len(cfg.channels), mode=mode, gains=cfg.gains, offsets=cfg.offsets, on_revolution=hook
    ) as adc:
        block = await adc.acquire(N, timeout=20)
    return block, used


@pytest.mark.parametrize("link", ["tcp", "pty"])
async def test_clean(rig, link):
    tap = WireTap(rig)
    block, used = await acquire_with_fault(rig, url_of(rig, link))
    s = block.stats
    counts = (s.revolutions_used, s.revolutions_dropped, s.frames_bad, s.link_drops, s.frames_lost)
    assert counts == (N, 0, 0, 0, 0), (s.drop_reasons, s.frame_errors)
    assert s.drop_reasons == {} and s.frame_errors == {}
    assert [r.rev for r in used] == list(range(used[0].rev, used[0].rev + N))
    check_block(rig, block, used, tap)


@pytest.mark.parametrize("link", ["tcp", "pty"])
async def test_corrupt_bytes(rig, link):
    tap = WireTap(rig)
    block, used = await acquire_with_fault(rig, url_of(rig, link), "corrupt_bytes", count=3)
    s = block.stats
    assert s.frames_bad >= 3 and s.bytes_skipped > 0
    assert 1 <= s.revolutions_dropped <= 2 and set(s.drop_reasons) == {"corrupt"}
    check_block(rig, block, used, tap)


@pytest.mark.parametrize("link", ["tcp", "pty"])
async def test_drop_frames(rig, link):
    tap = WireTap(rig)
    block, used = await acquire_with_fault(rig, url_of(rig, link), "drop_frames", count=3)
    s = block.stats
    assert s.frames_bad == 0 and s.bytes_skipped == 0 and s.frames_lost == 3
    # the revolution that lost frames (seq gap), and the next one if the frame after
    # the loss (it carries OVERRUN) is in it
    assert 1 <= s.revolutions_dropped <= 2 and "seq_gap" in s.drop_reasons
    assert set(s.drop_reasons) <= {"seq_gap", "overrun"}
    check_block(rig, block, used, tap)


@pytest.mark.parametrize("link", ["tcp", "pty"])
async def test_missing_trigger(rig, link):
    tap = WireTap(rig)
    block, used = await acquire_with_fault(rig, url_of(rig, link), "missing_trigger", count=2)
    s = block.stats
    assert s.drop_reasons == {"missing_trigger": 2} and s.revolutions_dropped == 2
    assert s.frames_bad == 0
    check_block(rig, block, used, tap)


@pytest.mark.parametrize("link", ["tcp", "pty"])
async def test_stall_clock(rig, link):
    tap = WireTap(rig)
    loop = asyncio.get_running_loop()

    ending = []

    def stall():  # the board clock stops for 10 revolutions (about 40 ms wall on an idle machine)
        rig.inject("stall_clock", on=True)
        first = rig.board.rev

        async def restart() -> None:  # counted in the board's revolutions, not 40 ms of wall time,
            # in which a starved simulator made none (no revolution dropped, failed under load)
            t_end = loop.time() + 10.0
            while (rig.board.rev - first) & 0xFFFFFFFF < 10 and loop.time() < t_end:
                await asyncio.sleep(0.005)
            rig.inject("stall_clock", on=False)

        ending.append(loop.create_task(restart()))

    block, used = await acquire_with_fault(rig, url_of(rig, link), stall)
    await asyncio.gather(*ending)
    s = block.stats
    assert s.drop_reasons.get("bad_clock", 0) >= 3 and set(s.drop_reasons) == {"bad_clock"}
    assert s.frames_bad == 0
    check_block(rig, block, used, tap)  # includes the orbit speed: no period from a stalled clock


@pytest.mark.parametrize("link", ["tcp", "pty"])
async def test_close_link_reconnects(rig, link, tmp_path):
    """The link drops (TCP connection aborted / pty hung up) and comes back. A pty
    comes back under whatever /dev/pts number is free, so the reader opens it by a
    symbolic link that the test re-points, as udev does for /dev/serial/by-id/."""
    tap = WireTap(rig)
    url = rig.adc_url
    tasks = []
    if link == "pty":
        url = str(tmp_path / "adc-by-id")
        os.symlink(rig.adc_pty_path, url)

    async def repoint():
        while rig.adc_pty_path is None:
            await asyncio.sleep(0.01)
        os.symlink(rig.adc_pty_path, url + ".new")
        os.replace(url + ".new", url)

    def fault():
        rig.inject("close_adc_link", reopen_after=0.1)
        if link == "pty":
            tasks.append(asyncio.ensure_future(repoint()))

    block, used = await acquire_with_fault(rig, url, fault)
    s = block.stats
    # a pty reader that reopens the by-id link before it is re-pointed (a loaded machine) opens
    # the hung-up pty once more and loses it again: a second drop
    assert s.link_drops == 1 if link == "tcp" else 1 <= s.link_drops <= 2, s
    # what the board converted while nobody read it is lost: its next frame says OVERRUN (seen
    # when the reconnect is slow, on a loaded machine)
    assert set(s.drop_reasons) <= {"link_drop", "seq_gap", "corrupt", "overrun"}
    check_block(rig, block, used, tap)
    await asyncio.gather(*tasks)


async def test_close_link_without_reconnect_raises(rig):
    async with AdcReader(rig.adc_url, reconnect=False) as adc:
        task = asyncio.ensure_future(adc.acquire(10_000, timeout=20))
        await asyncio.sleep(0.05)
        rig.inject("close_adc_link")
        with pytest.raises(DaqLinkError, match="closed|lost"):
            await task
        with pytest.raises(DaqLinkError, match="link is down"):
            await adc.acquire(10, timeout=5)


async def test_simultaneous_mode(tmp_path):
    from sim.config import SimConfig

    cfg = SimConfig()
    cfg.adc.mode = "simultaneous"
    async with SimRig(cfg, speedup=SPEEDUP, can_channel=None) as rig:
        rig.local_control(spin=SPIN, orbit=-ORBIT)  # backward whirl
        await asyncio.sleep(SETTLE)
        tap = WireTap(rig)
        block, used = await acquire_with_fault(rig, rig.adc_url, mode="simultaneous")
        assert block.stats.revolutions_dropped == 0 and block.theta.shape == (8, 360)
        check_block(rig, block, used, tap, orbit=-ORBIT, mode="simultaneous")


async def test_old_speed_is_discarded(rig):
    cfg = rig.config.adc
    async with AdcReader(rig.adc_pty_path, gains=cfg.gains) as adc:
        first = await adc.acquire(N, timeout=20)
        assert first.orbit_speed == pytest.approx(ORBIT, rel=2e-3)
        rig.local_control(spin=SPIN, orbit=2 * ORBIT)
        # the spindles jump to speed at the simulator's next tick, which a loaded machine delays:
        # wait for the board's tick at the new speed (its frames of the old speed are then written),
        # the reader reading meanwhile; then SETTLE more
        for _ in range(400):
            if rig.stream.last_speeds[1] == pytest.approx(2 * ORBIT, rel=1e-3):
                break
            await asyncio.sleep(0.025)
        await asyncio.sleep(SETTLE)
        second = await adc.acquire(N, timeout=20)
    assert second.orbit_speed == pytest.approx(2 * ORBIT, rel=2e-3)
    assert second.revs[0] > first.revs[-1] + 3
    truth = np.array(list(rig.true_phasors(SPIN, 2 * ORBIT).values()))
    np.testing.assert_allclose(second.phasors, truth, rtol=0.05, atol=0.05 * np.abs(truth).max())


async def test_failing_revolution_hook_ends_acquire(rig):
    def hook(r):
        raise RuntimeError("disk full")

    async with AdcReader(rig.adc_url, on_revolution=hook) as adc:
        with pytest.raises(RuntimeError, match="disk full"):
            await adc.acquire(N, timeout=5)


async def test_timeout_names_what_happened(rig):
    async with AdcReader(rig.adc_url, mode="simultaneous") as adc:  # the board scans sequentially
        with pytest.raises(
            DaqTimeoutError,
            match=r"no good revolution within 0.3 s; \d+ revolutions? dropped: \d+ in another A/D mode than the one "
            r"configured; frames \d+ good, \d+ bad, \d+ bytes skipped; no link drop; the board sends sequential frames "
            r"with 1 sample per slot \(flags bit 2 SIMULTANEOUS at byte 3, n_ch at byte 13\); configured: "
            r"simultaneous, 8 channels, so 8 samples per slot$",
        ):
            await adc.acquire(5, timeout=0.3)


async def test_unopenable_links():
    with pytest.raises(DaqLinkError, match="cannot connect"):
        async with AdcReader("socket://127.0.0.1:1"):
            pass
    with pytest.raises(DaqLinkError, match="/dev/does-not-exist: cannot open serial port"):
        async with AdcReader("/dev/does-not-exist"):
            pass
    with pytest.raises(DaqLinkError, match="unsupported URL"):
        async with AdcReader("rfc2217://127.0.0.1:1"):
            pass
    with pytest.raises(DaqLinkError, match=r"write socket://127\.0\.0\.1:5000 \(tcp:// is the Modbus"):
        async with AdcReader("tcp://127.0.0.1:5000"):
            pass


async def test_a_board_gone_ends_acquire_after_the_silence_bound(rig):
    """The board gone (nothing listens): acquire gives up once it has sent nothing for `silence`
    s, not at its timeout; a second call waits the bound again from its own start."""
    async with AdcReader(rig.adc_url, channels=len(rig.config.adc.channels)) as adc:
        await adc.acquire(5, timeout=20)
        rig.inject("adc_board_gone")
        loop = asyncio.get_running_loop()
        for waited in (0.4, 0.4):
            t0 = loop.time()
            with pytest.raises(
                DaqTimeoutError,
                match=r"the A/D board \(socket://[^)]+\) has sent nothing for \d\.\d s \(its link is down",
            ):
                await adc.acquire(10_000, timeout=30, silence=0.4)
            assert waited <= loop.time() - t0 < 3.0
        assert adc.silent_s > 0.8 and not adc.connected
