"""Revolution assembler: good frames -> complete, trigger-aligned revolutions. Pure.

A revolution is usable only when all 360 slots arrived with valid CRCs, in order,
under one rev number, from a TRIGGER frame on, with no OVERRUN and no seq gap
inside it (docs/protocols/adc-frames.md, "What a correct reader guarantees").
Anything else is dropped once per revolution and counted with its reason (see
:mod:`daq.stats`): the first reason found, also when the revolution breaks into
fragments (a fragment whose rev number changed mid-revolution, no frame lost,
belongs to the revolution of the frame before it). Revolutions of which every frame
was lost are counted when the next frame arrives, from the gap in the rev numbers,
with the reason of the lost frames (corrupt or seq_gap).

Vectorised over a batch of frames: frame i *continues* frame i-1 when its seq is
the next one (u16 wrap), the rev number is the same, its first slot is where
frame i-1 ended, it is not a TRIGGER frame, carries no OVERRUN and matches the
configured mode. Chains of continuing frames that start at a clean TRIGGER frame
and end at slot 360 are the good revolutions; their samples are contiguous in
the batch's sample buffer, so they are gathered with one fancy index.

Channel demultiplexing: sequential mode (one sample per slot) puts channel k at
slots k, k+C, k+2C, ... (C must divide 360); simultaneous mode gives every
channel all 360 slots. Angles: theta = 2 pi slot / 360 (orbit angle after the
trigger), so Fourier coefficients need no further phase correction.

The orbit period of revolution r is t_us(trigger r+1) - t_us(trigger r) (u32
wrap), so a revolution is released when the frame after it has arrived
(``flush()`` releases a held one with an unknown period). The board clock must
advance steadily from frame to frame up to the next trigger; a revolution over
which it stalled or jumped has no true period and is dropped (``bad_clock``).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from daq.adc_mode import SLOTS_PER_REV, AdcMode
from daq.frames import FLAG_OVERRUN, FLAG_SIMULTANEOUS, FLAG_TRIGGER, Frame, FrameBatch, slot_angle
from daq.revolution_checks import BreakReasons, steady_clock
from daq.stats import count
from rigunits import US

_U16 = 0xFFFF
_U32 = 0xFFFFFFFF
MAX_UNSEEN = 1 << 16  # a rev-number jump this large is a renumbering (board restart), not lost revolutions


@dataclass(frozen=True)
class Revolution:
    """One intact revolution in raw counts.

    counts: int16 (n_channels, samples_per_channel); slots: int (same shape), 0..359,
    theta = 2 pi slots / 360 rad. t_us: trigger time on the board clock (us, u32).
    period_s: orbit period measured to the next trigger (s), None if unknown.
    """

    rev: int
    t_us: int
    period_s: float | None
    counts: np.ndarray
    slots: np.ndarray

    @property
    def theta(self) -> np.ndarray:
        return slot_angle(self.slots)


@dataclass(frozen=True)
class RevolutionBatch:
    """Revolutions as arrays: counts (R, C, S) int16; rev, t_us (R,) int64;
    period_s (R,) float (NaN where unknown); slots (C, S) shared by all."""

    rev: np.ndarray
    t_us: np.ndarray
    period_s: np.ndarray
    counts: np.ndarray
    slots: np.ndarray

    def __len__(self) -> int:
        return len(self.rev)

    def take(self, index: slice) -> "RevolutionBatch":
        return RevolutionBatch(self.rev[index], self.t_us[index], self.period_s[index], self.counts[index], self.slots)

    def select(self, mask: np.ndarray) -> "RevolutionBatch":
        """The revolutions where ``mask`` (R,) bool is true."""
        return RevolutionBatch(self.rev[mask], self.t_us[mask], self.period_s[mask], self.counts[mask], self.slots)

    def revolutions(self) -> list[Revolution]:
        return [
            Revolution(int(r), int(t), None if np.isnan(p) else float(p), c, self.slots)
            for r, t, p, c in zip(self.rev, self.t_us, self.period_s, self.counts)
        ]

    @classmethod
    def concat(cls, parts: list["RevolutionBatch"], slots: np.ndarray) -> "RevolutionBatch":
        parts = [p for p in parts if len(p)]
        if not parts:
            z = np.zeros(0, np.int64)
            return cls(z, z, np.zeros(0), np.zeros((0, *slots.shape), np.int16), slots)
        if len(parts) == 1:
            return parts[0]
        return cls(
            np.concatenate([p.rev for p in parts]),
            np.concatenate([p.t_us for p in parts]),
            np.concatenate([p.period_s for p in parts]),
            np.concatenate([p.counts for p in parts]),
            slots,
        )


def channel_slots(channels: int, mode: AdcMode | str) -> np.ndarray:
    """Slot numbers (C, S) of each channel's samples (``mode``: an AdcMode or its word)."""
    if AdcMode(mode) is AdcMode.SEQUENTIAL:
        return np.arange(SLOTS_PER_REV).reshape(SLOTS_PER_REV // channels, channels).T.copy()
    return np.broadcast_to(np.arange(SLOTS_PER_REV), (channels, SLOTS_PER_REV)).copy()


class RevolutionAssembler:
    """Assemble good revolutions from decoded frames; count and drop the rest.

    Statistics (cumulative): ``revolutions_good``, ``revolutions_dropped``,
    ``drop_reasons`` (reason -> count), ``frames_discarded`` (frames of partial
    revolutions seen right after start/reset, before the first trigger: not faults),
    ``frames_lost`` (frames missing from the stream, by the frame counter's jumps: lost on
    the way, dropped by the board or too damaged to read; across a dropped link too, as the
    board counts on; modulo 65536, the counter's range).
    """

    def __init__(self, channels: int = 8, mode: AdcMode | str = AdcMode.SEQUENTIAL) -> None:
        try:
            mode = AdcMode(mode)
        except ValueError:
            raise ValueError(f"mode must be {' or '.join(repr(m.value) for m in AdcMode)}, not {mode!r}") from None
        # sequential: one sample per slot, C any divisor of 360; simultaneous: n_ch = C is a u8
        if mode is AdcMode.SEQUENTIAL and not (1 <= channels <= SLOTS_PER_REV and SLOTS_PER_REV % channels == 0):
            raise ValueError(f"channels={channels}: must divide 360 in sequential mode")
        if mode is AdcMode.SIMULTANEOUS and not 1 <= channels <= 255:
            raise ValueError(f"channels={channels}: must be 1..255 in simultaneous mode (n_ch is a u8)")
        self.channels = channels
        self.mode = mode
        self.n_ch = channels if mode is AdcMode.SIMULTANEOUS else 1  # samples per slot in a frame
        self._sim_flag = FLAG_SIMULTANEOUS if mode is AdcMode.SIMULTANEOUS else 0
        self.slots = channel_slots(channels, mode)
        self.revolutions_good = 0
        self.revolutions_dropped = 0
        self.drop_reasons: dict[str, int] = {}
        self.frames_discarded = 0
        self.frames_lost = 0
        self.mode_found = ""  # the last frame of another A/D mode, in words ("" if none came)
        self.frames_in_mode = self.frames_other_mode = 0  # frames of the configured mode, of another
        self.reset()

    def reset(self) -> None:
        """Forget everything in progress (a partial or held revolution, uncounted)."""
        # frames of the last chain that starts at a clean trigger: a revolution in
        # progress, or a complete one waiting for the next trigger (its period)
        self._carry = FrameBatch.empty()
        self._prev: tuple[int, int, int, int] | None = None  # (seq, rev, end slot, t_us) of the last frame
        self._recent_drops: deque[int] = deque(maxlen=8)
        self._discarding = True  # the tail of a revolution begun before start/reset is arriving

    def link_dropped(self) -> None:
        """The link dropped: a revolution in progress is lost (counted); a complete
        one waiting for its period is kept."""
        c = self._carry
        if len(c) and c.first_slot[-1] + c.n_slots[-1] != SLOTS_PER_REV:
            self._drop(int(c.rev[0]), "link_drop")
            self._carry = FrameBatch.empty()

    def _mode_words(self, flags: int, n_ch: int) -> str:
        """A frame of another A/D mode than the scan's, against the scan, in words."""
        seen = AdcMode.SIMULTANEOUS if flags & FLAG_SIMULTANEOUS else AdcMode.SEQUENTIAL
        return (
            f"the board sends {seen.value} frames with {n_ch} sample{'s' if n_ch != 1 else ''} per slot "
            f"(flags bit 2 SIMULTANEOUS at byte 3, n_ch at byte 13); configured: {self.mode.value}, "
            f"{self.channels} channels, so {self.n_ch} sample{'s' if self.n_ch != 1 else ''} per slot"
        )

    def _drop(self, rev: int, reason: str, *, fresh: bool = True, alias: int | None = None) -> None:
        """Count one dropped revolution; ``fresh=False``: a fragment of a revolution
        already counted if its rev number, or ``alias`` (the rev number the same
        revolution carried before it changed mid-revolution), was dropped lately."""
        if not fresh and (rev in self._recent_drops or alias in self._recent_drops):
            return
        self._recent_drops.append(rev)
        self.revolutions_dropped += 1
        count(self.drop_reasons, reason)

    def _count_unseen(
        self, rev: np.ndarray, prev_rev: np.ndarray, seq_ok: np.ndarray, why: BreakReasons, known_first: bool
    ) -> None:
        """Count the revolutions of which no frame arrived: after lost frames (a seq gap), the
        rev numbers strictly between the frame before and this one (u32 wrap; a jump of
        MAX_UNSEEN or more, or back, is a renumbering such as a board restart, not counted)."""
        gap = (rev - prev_rev) & _U32
        lost = ~seq_ok & (gap > 1) & (gap < MAX_UNSEEN)
        lost[0] &= known_first  # frame 0's predecessor is known only after the first batch
        for i in np.flatnonzero(lost):
            n = int(gap[i]) - 1
            self.revolutions_dropped += n
            count(self.drop_reasons, why(int(i)), n)

    def _count_lost_frames(
        self, seq: np.ndarray, p_seq: int, seq_ok: np.ndarray, carried: int, known_first: bool
    ) -> None:
        """Add the frames skipped by the frame counter's jumps before the new frames (those after
        the ``carried`` ones, already counted; frame 0's predecessor is known after the first batch)."""
        prev = np.concatenate(([p_seq], seq[:-1])).astype(np.int64)
        lost = ~seq_ok
        lost[:carried] = False
        lost[0] &= known_first
        self.frames_lost += int(((seq[lost].astype(np.int64) - prev[lost] - 1) & _U16).sum())

    def count_dropped(self, revs: np.ndarray | Sequence[int], reason: str = "off_speed") -> None:
        """Count revolutions (their rev numbers) that a reader left out after assembly."""
        for r in np.asarray(revs).ravel():
            self._drop(int(r), reason)

    def push(self, frame: Frame) -> list[Revolution]:
        return self.push_batch(FrameBatch.from_frames([frame])).revolutions()

    def flush(self) -> RevolutionBatch:
        """Release a complete revolution still waiting for the next trigger (period unknown)."""
        return self._assemble(FrameBatch.empty(), final=True)

    def push_batch(self, batch: FrameBatch) -> RevolutionBatch:
        """Good revolutions completed by these frames (each released once the frame
        after it has arrived, for its period)."""
        if not len(batch):
            return RevolutionBatch.concat([], self.slots)
        return self._assemble(batch, final=False)

    def _assemble(self, batch: FrameBatch, final: bool) -> RevolutionBatch:
        b = self._carry.concat(batch)
        f = len(b)
        if not f:
            return RevolutionBatch.concat([], self.slots)
        flags, seq, rev, fs, t = b.flags, b.seq, b.rev, b.first_slot, b.t_us
        end = fs + b.n_slots
        trig = (flags & FLAG_TRIGGER) != 0
        overrun = (flags & FLAG_OVERRUN) != 0
        mode_ok = ((flags & FLAG_SIMULTANEOUS) == self._sim_flag) & (b.n_ch == self.n_ch)
        self.frames_in_mode += int(mode_ok.sum())
        if not mode_ok.all():
            self.frames_other_mode += f - int(mode_ok.sum())
            i = int(np.flatnonzero(~mode_ok)[-1])
            self.mode_found = self._mode_words(int(flags[i]), int(b.n_ch[i]))
        # the previous frame's fields, shifted by one (frame 0's predecessor: self._prev)
        p_seq, p_rev, p_end, p_t = self._prev if self._prev is not None else (-2, -1, -1, 0)
        seq_ok = seq == ((np.concatenate(([p_seq], seq[:-1])) + 1) & _U16)
        prev_rev = np.concatenate(([p_rev], rev[:-1]))
        prev_end = np.concatenate(([p_end], end[:-1]))
        dt_frame = (t - np.concatenate(([p_t], t[:-1]))) & _U32  # board clock step (us)
        clock_ok = (dt_frame > 0) & (dt_frame < 1 << 31)
        cont = seq_ok & (rev == prev_rev) & (fs == prev_end) & ~trig & ~overrun & mode_ok & clock_ok
        # frame 0 starts the carried chain, or continues a fragment that was not carried
        # (dropped, or discarded after start/reset), or starts anew
        tail = bool(cont[0]) and not len(self._carry)
        cont[0] = False
        discard_first = self._prev is None or (tail and self._discarding)
        starts = np.flatnonzero(~cont)
        lasts = np.append(starts[1:] - 1, f - 1)
        clean_start = trig[starts] & ~overrun[starts] & mode_ok[starts]
        complete = clean_start & (end[lasts] == SLOTS_PER_REV)

        # the last clean chain waits in the carry: in progress, or complete but its
        # period (the next frame) not known yet
        carry_from = None
        if clean_start[-1] and not final:
            carry_from = int(starts[-1])
            complete[-1] = False

        # period: to the next frame if it is the next revolution's trigger
        good_first, good_last = starts[complete], lasts[complete]
        nxt = np.minimum(good_last + 1, f - 1)
        has_next = good_last + 1 < f
        is_next_trig = has_next & trig[nxt] & (rev[nxt] == ((rev[good_first] + 1) & _U32))
        period_us = ((t[nxt] - t[good_first]) & _U32).astype(np.float64)
        steady = steady_clock(dt_frame, b.n_slots, good_first, good_last, period_us)
        bad_clock = is_next_trig & ~steady
        period = np.where(is_next_trig & steady, period_us * US, np.nan)

        # fault attribution for chains that are not good revolutions (rare: Python loop)
        why = BreakReasons(b, trig, overrun, mode_ok, seq_ok, prev_rev, clock_ok)
        for k in np.flatnonzero(~complete):
            a, z = int(starts[k]), int(lasts[k])
            r = int(rev[a])
            if a == carry_from:
                continue
            if clean_start[k]:
                self._drop(r, why(z + 1) if z + 1 < f else "incomplete")
            elif a == 0 and discard_first:
                self.frames_discarded += z - a + 1  # tail of a revolution begun before start/reset
            elif a == 0 and tail:
                pass  # more of a fragment already counted
            elif trig[a]:
                self._drop(r, "overrun" if overrun[a] else "mode_mismatch")
            else:
                reason = why(a)
                # no frame lost, mid-revolution: the frame before's revolution, its rev number changed
                renumbered = reason == "rev_mismatch" and 0 < fs[a] and prev_end[a] < SLOTS_PER_REV
                if reason in ("slot_gap", "rev_mismatch") or (fs[a] == 0 and reason not in ("corrupt", "seq_gap")):
                    reason = "missing_trigger"  # the chain restarted without a TRIGGER frame
                # a fragment from slot 0 on is a revolution of its own (a missed trigger
                # does not advance the rev number); a later one may belong to one counted
                self._drop(r, reason, fresh=bool(fs[a] == 0), alias=int(prev_rev[a]) if renumbered else None)
        for r in rev[good_first[bad_clock]]:
            self._drop(int(r), "bad_clock")
        self._count_unseen(rev, prev_rev, seq_ok, why, known_first=self._prev is not None)
        self._count_lost_frames(seq, p_seq, seq_ok, len(self._carry), known_first=self._prev is not None)

        self._carry = b.select(carry_from) if carry_from is not None else FrameBatch.empty()
        self._discarding = discard_first and len(starts) == 1 and not clean_start[0]
        self._prev = (int(seq[-1]), int(rev[-1]), int(end[-1]), int(t[-1])) if f else self._prev

        good_first, period = good_first[~bad_clock], period[~bad_clock]
        r_count = len(good_first)
        if not r_count:
            return RevolutionBatch.concat([], self.slots)
        idx = b.start[good_first][:, None] + np.arange(SLOTS_PER_REV * self.n_ch)
        flat = b.samples[idx]  # (R, 360 * n_ch), slot-major
        if self.mode is AdcMode.SEQUENTIAL:
            counts = flat.reshape(r_count, SLOTS_PER_REV // self.channels, self.channels)
        else:
            counts = flat.reshape(r_count, SLOTS_PER_REV, self.channels)
        self.revolutions_good += r_count
        return RevolutionBatch(
            rev[good_first], t[good_first], period, np.ascontiguousarray(counts.transpose(0, 2, 1)), self.slots
        )
