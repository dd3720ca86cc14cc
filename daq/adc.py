"""AdcReader: the A/D board's byte stream -> averaged, phase-true revolutions (async).

    async with AdcReader("socket://127.0.0.1:5000", channels=8) as adc:
        block = await adc.acquire(50, timeout=10.0)    # AveragedBlock
        block.phasors, block.orbit_speed, block.stats

The link is read continuously from the moment the reader opens (so neither the
OS buffers nor the board back up), decoded (daq.frames) and assembled into
revolutions (daq.revolutions) inside the event loop's read callback. Outside
``acquire`` revolutions are thrown away. ``acquire`` first consumes whatever the
OS already holds for the link, forgets the revolution in progress (old speed),
then averages the next ``n`` good revolutions. Keep the reader open while the
drives settle (as the sweep does): data a sender had queued but not yet sent
when ``acquire`` was called cannot be told apart from new data. A dropped link is reopened with
jittered exponential back-off (``reconnect=True``); the revolution in progress is
counted as dropped (``link_drop``).
"""

from __future__ import annotations

import asyncio
import random
from collections.abc import Callable, Sequence
from dataclasses import replace

from daq.averager import AveragedBlock, StreamingAverager
from daq.errors import DaqError, DaqLinkError, DaqTimeoutError
from daq.frames import FrameDecoder
from daq.revolutions import Revolution, RevolutionAssembler, RevolutionBatch
from daq.stats import AcquisitionStats
from daq.transport import ByteLink, open_link


class _Collection:
    """One ``acquire`` in progress."""

    def __init__(self, averager: StreamingAverager, future: asyncio.Future,
                 on_revolution: Callable[[Revolution], None] | None) -> None:
        self.averager = averager
        self.future = future
        self.on_revolution = on_revolution

    def push(self, revs: RevolutionBatch) -> int:
        """Feed revolutions; returns how many were used."""
        if self.future.done():
            return 0
        need = self.averager.n_revolutions - self.averager.count
        if len(revs) > need:
            revs = revs.take(slice(0, need))
        if self.on_revolution is not None:
            try:
                for r in revs.revolutions():
                    self.on_revolution(r)
            except Exception as err:  # the caller's hook failed: end this acquire with its error
                self.future.set_exception(err)
                return 0
        blocks = self.averager.push_batch(revs)
        if blocks:
            self.future.set_result(blocks[0])
        return len(revs)


class AdcReader:
    """Async context manager reading the clocked A/D board at ``url``.

    url: ``socket://host:port``, a serial device or pty path (see daq.transport).
    channels, mode: the board's scan list size and ``sequential``/``simultaneous``.
    gains, offsets: per channel, engineering value = gain * counts + offset
    (default raw counts). on_revolution: called with every revolution that goes
    into an average (raw counts, for storage). ``stats``: cumulative counters.
    """

    def __init__(self, url: str, *, channels: int = 8, mode: str = "sequential",
                 gains: Sequence[float] | None = None, offsets: Sequence[float] | None = None,
                 on_revolution: Callable[[Revolution], None] | None = None,
                 reconnect: bool = True, open_timeout: float = 5.0,
                 max_backoff: float = 1.0) -> None:
        self.url = url
        self.channels, self.mode = channels, mode
        self.gains, self.offsets = gains, offsets
        self.on_revolution = on_revolution
        self.reconnect = reconnect
        self.open_timeout = open_timeout
        self.max_backoff = max_backoff
        self._decoder = FrameDecoder()
        self._assembler = RevolutionAssembler(channels, mode)  # raises ValueError on a bad scan
        self._link: ByteLink | None = None
        self._collection: _Collection | None = None
        self._reconnect_task: asyncio.Task | None = None
        self._closed = False
        self._revolutions_used = 0
        self.link_drops = 0
        self.link_error: Exception | None = None

    async def __aenter__(self) -> AdcReader:
        await self.open()
        return self

    async def __aexit__(self, *exc) -> None:
        await self.aclose()

    async def open(self) -> None:
        """Open the link; raises DaqLinkError if it cannot be opened."""
        self._closed = False
        self._link = await open_link(self.url, self._on_data, self._on_lost, timeout=self.open_timeout)

    async def aclose(self) -> None:
        """Close the link and stop reconnecting (idempotent)."""
        self._closed = True
        task, self._reconnect_task = self._reconnect_task, None
        if task is not None:
            task.cancel()
            try:
                await task
            except asyncio.CancelledError:
                pass
        if self._link is not None:
            self._link.close()
            self._link = None
        self._fail(DaqLinkError(f"{self.url}: reader closed"))

    @property
    def connected(self) -> bool:
        return self._link is not None and not self._link.closed

    @property
    def stats(self) -> AcquisitionStats:
        d, a = self._decoder, self._assembler
        return AcquisitionStats(
            frames_good=d.frames_good, frames_bad=d.frames_bad, bytes_skipped=d.bytes_skipped,
            revolutions_used=self._revolutions_used, revolutions_dropped=a.revolutions_dropped,
            drop_reasons=dict(a.drop_reasons), frame_errors=dict(d.frame_errors),
            link_drops=self.link_drops,
        )

    # ------------------------------------------------------------ data path
    def _on_data(self, data: bytes) -> None:
        try:
            revs = self._assembler.push_batch(self._decoder.feed_batch(data))
        except Exception as err:  # a bug, never bad input: make acquire() raise it, not time out
            self._fail(err)
            raise
        if self._collection is not None and len(revs):
            self._revolutions_used += self._collection.push(revs)

    def _on_lost(self, err: Exception) -> None:
        self.link_drops += 1
        self._decoder.reset()
        self._assembler.link_dropped()
        self.link_error = err
        if self._closed:
            return
        if not self.reconnect:
            self._fail(err)
            return
        self._reconnect_task = asyncio.get_running_loop().create_task(
            self._reconnect_loop(), name=f"adc-reconnect {self.url}")

    def _fail(self, err: Exception) -> None:
        c = self._collection
        if c is not None and not c.future.done():
            c.future.set_exception(err)

    async def _reconnect_loop(self) -> None:
        delay = 0.02
        while not self._closed:
            try:
                self._link = await open_link(self.url, self._on_data, self._on_lost, timeout=self.open_timeout)
                self._reconnect_task = None
                return
            except DaqLinkError as err:
                self.link_error = err
            await asyncio.sleep(delay * random.uniform(0.5, 1.0))
            delay = min(delay * 2, self.max_backoff)

    # ------------------------------------------------------------ acquisition
    async def acquire(self, n_revolutions: int = 50, *, timeout: float) -> AveragedBlock:
        """Average the next ``n_revolutions`` good revolutions received after this call.

        Raises DaqTimeoutError (with the counts seen) if they do not arrive within
        ``timeout`` seconds, DaqLinkError if the link drops and ``reconnect`` is off.
        """
        if self._collection is not None:
            raise DaqError("acquire() is already running on this reader")
        if self._closed or self._link is None:
            raise DaqLinkError(f"{self.url}: reader is not open")
        if not self.connected and self._reconnect_task is None:
            raise DaqLinkError(f"{self.url}: link is down ({self.link_error})")
        # bytes already received (waiting in the OS) were converted before this call:
        # they pass through the decoder and assembler while nothing is collecting
        if self.connected:
            self._on_data(self._link.read_ready())
        self._assembler.reset()
        start = self.stats
        loop = asyncio.get_running_loop()
        averager = StreamingAverager(n_revolutions, self.gains, self.offsets)
        self._collection = _Collection(averager, loop.create_future(), self.on_revolution)
        try:
            block = await asyncio.wait_for(self._collection.future, timeout)
        except asyncio.TimeoutError:
            s = self.stats.since(start)
            got = averager.count
            what = "no good revolution" if got == 0 else f"only {got} of {n_revolutions} good revolutions"
            raise DaqTimeoutError(
                f"{self.url}: {what} within {timeout:g} s (frames good {s.frames_good}, bad {s.frames_bad}, "
                f"bytes skipped {s.bytes_skipped}, revolutions dropped {s.revolutions_dropped} "
                f"{s.drop_reasons or ''}, link drops {s.link_drops}"
                + (f", last link error: {self.link_error}" if s.link_drops or not self.connected else "") + ")"
            ) from None
        finally:
            self._collection = None
        return replace(block, stats=self.stats.since(start))
