"""AdcReader: the A/D board's byte stream -> averaged, phase-true revolutions (async).

    async with AdcReader("socket://127.0.0.1:5000", channels=8) as adc:
        block = await adc.acquire(50, timeout=10.0)    # AveragedBlock (the fixed rule)
        block = await adc.acquire(AveragingRule.adaptive(0.005, 10, 200), timeout=2.0, per_revolution=3.0)
        block.phasors, block.uncertainty, block.raw_counts, block.stop_reason, block.stats

The link is read continuously from the moment the reader opens (so neither the
OS buffers nor the board back up), decoded (daq.frames) and assembled into
revolutions (daq.revolutions) inside the event loop's read callback. Outside
``acquire`` revolutions are thrown away. ``acquire`` first consumes whatever the
OS already holds for the link, forgets the revolution in progress (old speed),
then averages the next good revolutions as its rule says (daq.averager). Keep
the reader open while the drives settle (as the sweep does): data a sender had
queued but not yet sent when ``acquire`` was called cannot be told apart from
new data. A dropped link is reopened after growing, jittered delays
(daq.backoff, ``reconnect=True``) that start again from the shortest only once
good frames arrived on the new link; the revolution in progress is counted as
dropped (``link_drop``).
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np

from daq.averaging_rule import AveragingRule
from daq.averager import AveragedBlock, StreamingAverager
from daq.adc_mode import AdcMode
from daq.backoff import Backoff
from daq.errors import DaqError, DaqLinkError, DaqTimeoutError
from daq.frames import CRC_SIZE, HEADER_SIZE, FrameDecoder
from daq.revolutions import Revolution, RevolutionAssembler, RevolutionBatch
from daq.stats import AcquisitionStats, dropped_words
from daq.transport import ByteLink, open_link
from rigunits import in_rpm


#: s after a silence bound is passed by which acquire() has noticed it
SILENCE_CHECK_S = 0.05
#: s without a byte from an open link, at a timeout, that its message calls a stopped stream
STOPPED_S = 1.0
#: s into an acquisition after which frames all of another A/D mode (none of the configured one) fail it,
#: as do noise_bytes(channels) or more skipped without one valid frame
MODE_CHECK_S = 1.0
#: s between looks at what came, from MODE_CHECK_S on, while no frame of the configured mode has
NOISE_CHECK_S = 0.1


def noise_bytes(channels: int) -> int:
    """Bytes skipped without one valid frame that fail an acquisition (4096 at least): more than a
    legitimate start skips at any orbit speed, three of the largest frames of `channels` (255 slots:
    the rest of one a link opened in, one held at a link drop, the rest of one the new link opened in)."""
    return max(4096, 3 * (HEADER_SIZE + 2 * 255 * channels + CRC_SIZE))


def _measured_orbit(orbit_speed: float | None, measured: float | None) -> str:
    """The timing disk's orbit speed ``measured`` (rad/s) of the revolutions left out for it, against the set
    one, in words ("" when none was left out): a drive not at its setpoint, or another spindle turning."""
    if orbit_speed is None or measured is None:
        return ""
    rpm, set_rpm = in_rpm(measured), in_rpm(orbit_speed)
    return f"; the timing disk measured the orbit at {rpm:.1f} rpm, the block's |Omega| is {set_rpm:.1f} rpm"


class _Collection:
    """One ``acquire`` in progress."""

    def __init__(
        self,
        averager: StreamingAverager,
        future: asyncio.Future[AveragedBlock],
        on_revolution: Callable[[Revolution], None] | None,
        drop: Callable[[np.ndarray], None] = lambda revs: None,
    ) -> None:
        self.averager = averager
        self.drop = drop  # counts revolutions left out (their rev numbers) as off_speed
        self.future = future
        self.on_revolution = on_revolution
        self.period: float | None = None  # first orbit period measured (s)
        self.off_speed: float | None = None  # rad/s of the last batch's median period, all off the set speed

    def push(self, revs: RevolutionBatch) -> int:
        """Feed revolutions; returns how many were used."""
        if self.future.done():
            return 0
        off = self.averager.rule.off_speed(revs.period_s)
        period = float(np.median(revs.period_s)) if off.all() else 0.0
        self.off_speed = 2 * np.pi / period if period > 0 else None
        if off.any():  # turned before the drive reached its setpoint (or off it): not this block's
            self.drop(revs.rev[off])
            revs = revs.select(~off)
            if not len(revs):
                return 0
        if self.period is None:
            known = revs.period_s[~np.isnan(revs.period_s)]
            self.period = float(known[0]) if len(known) else None
        used, block = self.averager.take(revs)
        if self.on_revolution is not None and used:
            try:
                for r in revs.take(slice(0, used)).revolutions():
                    self.on_revolution(r)
            except Exception as err:  # noqa: BLE001 - the caller's hook failed: end this acquire with its error
                self.future.set_exception(err)
                return used
        if block is not None:
            self.future.set_result(block)
        return used


class AdcReader:
    """Async context manager reading the clocked A/D board at ``url``.

    url: ``socket://host:port``, a serial device or pty path (see daq.transport).
    channels, mode: the board's scan list size and its AdcMode (or the mode's word).
    gains, offsets: per channel, engineering value = gain * counts + offset
    (default raw counts). on_revolution: called with every revolution that goes
    into an average (the block carries their raw counts too). max_backoff: the
    longest delay (s) between reconnect attempts. ``stats``: cumulative counters;
    ``reconnects``: reconnect attempts made; ``silent_s``: wall s since the last byte came.
    """

    def __init__(
        self,
        url: str,
        *,
        channels: int = 8,
        mode: AdcMode | str = AdcMode.SEQUENTIAL,
        gains: Sequence[float] | None = None,
        offsets: Sequence[float] | None = None,
        on_revolution: Callable[[Revolution], None] | None = None,
        reconnect: bool = True,
        open_timeout: float = 5.0,
        max_backoff: float = 2.0,
        backoff: Backoff | None = None,
    ) -> None:
        self.url = url
        self.channels = channels
        self.gains, self.offsets = gains, offsets
        self.on_revolution = on_revolution
        self.reconnect = reconnect
        self.open_timeout = open_timeout
        self.backoff = backoff or Backoff(maximum=max_backoff)
        self._decoder = FrameDecoder()
        self._assembler = RevolutionAssembler(channels, mode)  # raises ValueError on a bad scan
        self.mode = self._assembler.mode
        self._link: ByteLink | None = None
        self._collection: _Collection | None = None
        self._reconnect_task: asyncio.Task[None] | None = None
        self._closed = False
        self._flowed = False  # good frames arrived on the current link
        self._revolutions_used = 0
        self.link_drops = 0
        self.reconnects = 0
        self.link_error: Exception | None = None
        self._heard_at = time.monotonic()  # the last byte's arrival (or the reader's creation)

    async def __aenter__(self) -> AdcReader:
        await self.open()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.aclose()

    async def open(self) -> None:
        """Open the link; raises DaqLinkError if it cannot be opened."""
        self._closed = False
        self._heard_at = time.monotonic()
        self._link = await open_link(self.url, self._on_data, self._on_lost, timeout=self.open_timeout)
        self._flowed = False

    async def aclose(self) -> None:
        """Close the link and stop reconnecting (idempotent)."""
        self._closed = True
        task, self._reconnect_task = self._reconnect_task, None
        try:
            if task is not None:
                task.cancel()
                await asyncio.wait([task])  # a cancel of the caller goes on to the caller
        finally:
            if self._link is not None:
                self._link.close()
                self._link = None
            self._fail(DaqLinkError(f"{self.url}: reader closed"))

    @property
    def silent_s(self) -> float:
        """Wall s since the board's last byte arrived (since the reader was opened, before any)."""
        return time.monotonic() - self._heard_at

    @property
    def connected(self) -> bool:
        return self._link is not None and not self._link.closed

    @property
    def link_state(self) -> str:
        """The link in words: 'open', or 'down' with its error when one is known."""
        if self.connected:
            return "open"
        return "down" if self.link_error is None else "down: " + str(self.link_error).removeprefix(f"{self.url}: ")

    def silence(self) -> str:
        """The board's silence in words: how long it has sent nothing, its link, and the likely
        cause (link open: no slot edge clocked; link down: the reconnect attempts so far)."""
        said = f"the A/D board ({self.url}) has sent nothing for {self.silent_s:.1f} s (its link is {self.link_state}"
        if self.connected:
            return said + ": no slot edge clocked? the orbit spindle stopped or the timing disk's sensor off)"
        return said + f"; {self.reconnects} reconnect attempts so far)"

    @property
    def stats(self) -> AcquisitionStats:
        d, a = self._decoder, self._assembler
        return AcquisitionStats(
            frames_good=d.frames_good,
            frames_bad=d.frames_bad,
            bytes_skipped=d.bytes_skipped,
            revolutions_used=self._revolutions_used,
            revolutions_dropped=a.revolutions_dropped,
            drop_reasons=dict(a.drop_reasons),
            frame_errors=dict(d.frame_errors),
            link_drops=self.link_drops,
            frames_lost=a.frames_lost,
        )

    # ------------------------------------------------------------ data path
    def _on_data(self, data: bytes) -> None:
        if data:
            self._heard_at = time.monotonic()
        try:
            frames = self._decoder.feed_batch(data)
            revs = self._assembler.push_batch(frames)
        except Exception as err:  # a bug, never bad input: make acquire() raise it, not time out
            self._fail(err)
            raise
        if not self._flowed and len(frames):
            self._flowed = True
            self.backoff.reset()
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
        if self._reconnect_task is None:
            self._reconnect_task = asyncio.get_running_loop().create_task(
                self._reconnect_loop(), name=f"adc-reconnect {self.url}"
            )

    def _fail(self, err: Exception) -> None:
        c = self._collection
        if c is not None and not c.future.done():
            c.future.set_exception(err)

    async def _reconnect_loop(self) -> None:
        """Wait the next backoff delay, try to reopen; repeat until open or closed."""
        while not self._closed:
            await asyncio.sleep(self.backoff.next_delay())
            self.reconnects += 1
            try:
                link = await open_link(self.url, self._on_data, self._on_lost, timeout=self.open_timeout)
            except DaqLinkError as err:
                self.link_error = err
                continue
            self._link, self._flowed, self._reconnect_task = link, False, None
            return

    # ------------------------------------------------------------ acquisition
    async def acquire(
        self,
        rule: AveragingRule | int = 50,
        *,
        timeout: float,
        per_revolution: float | None = None,
        silence: float | None = None,
    ) -> AveragedBlock:
        """Average the good revolutions received after this call as ``rule`` says
        (an ``AveragingRule``, or n for the fixed rule of n revolutions).

        Waits ``timeout`` s; with ``per_revolution`` = F, once the orbit period P is
        measured the wait grows to ``timeout + F * rule.max_revolutions * P``. Raises
        DaqTimeoutError (with the counts seen) if the block is not complete in time, once
        every frame of the first MODE_CHECK_S s is of another A/D mode (or, from then on, once
        noise_bytes(channels) were skipped without one valid frame), or once the board has
        sent nothing for ``silence`` s, counted from this call at the earliest (None: no such
        bound), DaqLinkError if the link drops and ``reconnect`` is off."""
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
        averager = StreamingAverager(rule, self.gains, self.offsets)
        self._collection = c = _Collection(
            averager, loop.create_future(), self.on_revolution, self._assembler.count_dropped
        )
        t0, modes = loop.time(), (self._assembler.frames_in_mode, self._assembler.frames_other_mode)
        try:
            while not c.future.done():
                limit = timeout
                if per_revolution and c.period:  # the orbit period is known: wait for the revolutions
                    limit += per_revolution * averager.n_revolutions * c.period
                left = t0 + limit - loop.time()
                waited = loop.time() - t0
                if left <= 0 or self._all_another_mode(modes, waited) or self._only_noise(start, waited):
                    raise self._timeout_error(start, averager, min(limit, waited), c.off_speed)
                left = min(left, max(t0 + MODE_CHECK_S - loop.time(), 0.0) or left)
                if waited >= MODE_CHECK_S and self._assembler.frames_in_mode == modes[0]:  # nothing good yet
                    left = min(left, NOISE_CHECK_S)
                if silence is not None:  # counted from this call at the earliest: each call waits for the board
                    quiet = min(self.silent_s, loop.time() - t0)
                    if quiet > silence:
                        raise self._silence_error(start, averager)
                    left = min(left, silence - quiet + SILENCE_CHECK_S)
                await asyncio.wait({c.future}, timeout=left)
            block = c.future.result()
        finally:
            self._collection = None
        return replace(block, stats=self.stats.since(start))

    def _all_another_mode(self, before: tuple[int, int], waited: float) -> bool:
        """Whether, `waited` s (at least MODE_CHECK_S) into an acquisition, the frames that came
        since (`before`: the assembler's counts of frames in the configured mode and in another,
        then) are all of another A/D mode: no revolution of them can ever be good."""
        a = self._assembler
        return waited >= MODE_CHECK_S and a.frames_in_mode == before[0] and a.frames_other_mode > before[1]

    def _only_noise(self, start: AcquisitionStats, waited: float) -> bool:
        """Whether, `waited` s (at least MODE_CHECK_S) into an acquisition, bytes kept coming
        (noise_bytes at least) without one valid frame: another device's stream, or a serial
        port at another baud rate or parity than the board's. No revolution can come of it."""
        if waited < MODE_CHECK_S:
            return False
        s = self.stats.since(start)
        return not s.frames_good and s.bytes_skipped >= noise_bytes(self.channels)

    def _silence_error(self, start: AcquisitionStats, averager: StreamingAverager) -> DaqTimeoutError:
        s = self.stats.since(start)
        return DaqTimeoutError(
            f"{self.silence()}; {averager.count} of {averager.n_revolutions} good revolutions, link drops {s.link_drops}"
        )

    def _timeout_error(
        self, start: AcquisitionStats, averager: StreamingAverager, waited: float, measured: float | None = None
    ) -> DaqTimeoutError:
        """`measured`: the orbit speed (rad/s) of the last revolutions left out for it, by the timing disk."""
        s = self.stats.since(start)
        got, want = averager.count, averager.n_revolutions
        what = "no good revolution" if got == 0 else f"only {got} of {want} good revolutions"
        drops = (
            f"link dropped {s.link_drops} time{'s' if s.link_drops != 1 else ''}" if s.link_drops else "no link drop"
        )
        if not s.link_drops and not self.connected:
            drops = "link down"
        return DaqTimeoutError(
            f"{self.url}: {what} within {waited:.4g} s; {dropped_words(s)}; frames {s.frames_good} good, "
            f"{s.frames_bad} bad, {s.bytes_skipped} bytes skipped; {drops}"
            + (f" (last link error: {self.link_error})" if s.link_drops or not self.connected else "")
            + self._what_came(s)
            + _measured_orbit(averager.rule.orbit_speed, measured),
            heard=bool(s.frames_good or s.frames_bad or s.bytes_skipped),
            orbit_measured=measured,
        )

    def _what_came(self, s: AcquisitionStats) -> str:
        """Why the bytes that came made no good revolution, where the counts alone do not say
        (frames of another A/D mode, bytes without one valid frame, a stream stopped); "" else."""
        if s.drop_reasons.get("mode_mismatch") and self._assembler.mode_found:
            return f"; {self._assembler.mode_found}"
        if not s.frames_good and (s.bytes_skipped or s.frames_bad):
            refused = ", ".join(f"{k} {v}" for k, v in sorted(s.frame_errors.items()))
            return (
                "; no valid frame in what came: each starts with the sync bytes 0xA5 0x5A (byte 0..1), "
                "version 1 (byte 2), and passes its CRC"
                + (f" (frames refused: {refused})" if refused else "")
                + "; is this the A/D board's frame stream?"
            )
        if self.connected and self.silent_s >= STOPPED_S:
            pending = self._decoder.pending
            inside = f", in the middle of a frame ({pending} bytes of it came)" if pending > 1 else ""
            return f"; then the stream stopped{inside}: {self.silence()}"
        return ""
