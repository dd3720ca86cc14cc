"""Decoder of the A/D board's frames (docs/protocols/adc-frames.md, v1). Pure: no I/O.

``FrameDecoder.feed(bytes)`` takes the byte stream in arbitrary pieces and returns
the frames that passed every check (sync, version, header fields, length, CRC).
It never raises on bad bytes: garbage, damaged frames and false sync patterns
inside payloads are skipped and counted, and the decoder resynchronises on the
next sync whose frame passes its CRC.

Work per frame is a handful of C calls (``bytes.find`` for the sync search,
``struct.unpack_from`` for the header, ``binascii.crc_hqx`` for the CRC); samples
are never touched one by one: the payloads of a whole ``feed`` are joined and
converted with one ``np.frombuffer``. ``feed_batch`` returns them as arrays
(:class:`FrameBatch`), which the revolution assembler consumes without building
a Python object per frame.
"""

from __future__ import annotations

import struct
from binascii import crc_hqx
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from daq.adc_mode import SLOTS_PER_REV
from daq.stats import count

SYNC = b"\xa5\x5a"
VERSION = 1
FLAG_TRIGGER = 0x01
FLAG_OVERRUN = 0x02
FLAG_SIMULTANEOUS = 0x04
HEADER_SIZE = 18  # sync(2) version flags seq(2) rev(4) first_slot(2) n_slots n_ch t_us(4)
CRC_SIZE = 2
MAX_FRAME = HEADER_SIZE + 2 * 255 * 255 + CRC_SIZE
_LAST_SYNC_BYTE0 = SYNC[0]
_RESERVED = 0xFF & ~(FLAG_TRIGGER | FLAG_OVERRUN | FLAG_SIMULTANEOUS)
_CHECKED = struct.Struct("<2xBB6xHBB")  # version flags first_slot n_slots n_ch
_HEADER_DTYPE = np.dtype(
    [
        ("sync", "<u2"),
        ("version", "u1"),
        ("flags", "u1"),
        ("seq", "<u2"),
        ("rev", "<u4"),
        ("first_slot", "<u2"),
        ("n_slots", "u1"),
        ("n_ch", "u1"),
        ("t_us", "<u4"),
    ]
)


@dataclass(frozen=True)
class Frame:
    """One frame that passed its CRC. ``samples``: int16 counts, shape (n_slots, n_ch)."""

    flags: int
    seq: int
    rev: int
    first_slot: int
    n_slots: int
    n_ch: int
    t_us: int
    samples: np.ndarray
    skipped_before: int = 0  # bytes discarded between the previous good frame and this one

    @property
    def trigger(self) -> bool:
        return bool(self.flags & FLAG_TRIGGER)

    @property
    def overrun(self) -> bool:
        return bool(self.flags & FLAG_OVERRUN)

    @property
    def simultaneous(self) -> bool:
        return bool(self.flags & FLAG_SIMULTANEOUS)


def slot_angle(slots: npt.ArrayLike) -> np.ndarray:
    """The orbit angle (rad) after the trigger of timing-disk slot numbers: 2 pi slot / 360
    (SLOTS_PER_REV), the theta of every phasor q = dc + Re(q_bar e^{i theta})."""
    return np.asarray(slots, dtype=float) * (2 * np.pi / SLOTS_PER_REV)


def _header_of(f: Frame) -> tuple[int, ...]:
    """A frame's header fields in FrameBatch column order."""
    return (f.flags, f.seq, f.rev, f.first_slot, f.n_slots, f.n_ch, f.t_us, f.skipped_before)


@dataclass(frozen=True)
class FrameBatch:
    """Good frames of one ``feed`` as arrays (all int64, shape (F,)).

    ``start[i]`` is the index in ``samples`` (int16, 1-D, all payloads in stream
    order, slot-major) of frame i's first sample; it has ``n_slots[i]*n_ch[i]``.
    """

    flags: np.ndarray
    seq: np.ndarray
    rev: np.ndarray
    first_slot: np.ndarray
    n_slots: np.ndarray
    n_ch: np.ndarray
    t_us: np.ndarray
    skipped_before: np.ndarray
    start: np.ndarray
    samples: np.ndarray

    def __len__(self) -> int:
        return len(self.seq)

    def header_columns(self) -> tuple[np.ndarray, ...]:
        """The per-frame header columns, in constructor order (before ``start``)."""
        return (
            self.flags,
            self.seq,
            self.rev,
            self.first_slot,
            self.n_slots,
            self.n_ch,
            self.t_us,
            self.skipped_before,
        )

    @classmethod
    def empty(cls) -> "FrameBatch":
        z = np.zeros(0, np.int64)
        return cls(z, z, z, z, z, z, z, z, z, np.zeros(0, np.int16))

    @classmethod
    def from_frames(cls, frames: list[Frame]) -> "FrameBatch":
        if not frames:
            return cls.empty()
        cols = np.array([_header_of(f) for f in frames], np.int64).T
        sizes = np.array([f.n_slots * f.n_ch for f in frames], np.int64)
        start = np.concatenate(([0], np.cumsum(sizes)[:-1]))
        samples = np.concatenate([np.ascontiguousarray(f.samples, np.int16).ravel() for f in frames])
        return cls(*cols, start, samples)

    def select(self, first: int) -> "FrameBatch":
        """Frames ``first:`` with their samples re-based to a compact buffer."""
        if first >= len(self):
            return FrameBatch.empty()
        s0 = int(self.start[first])
        cols = [c[first:].copy() for c in self.header_columns()]
        return FrameBatch(*cols, self.start[first:] - s0, self.samples[s0:].copy())

    def concat(self, other: "FrameBatch") -> "FrameBatch":
        if not len(self):
            return other
        if not len(other):
            return self
        cols = [np.concatenate(pair) for pair in zip(self.header_columns(), other.header_columns())]
        start = np.concatenate((self.start, other.start + len(self.samples)))
        return FrameBatch(*cols, start, np.concatenate((self.samples, other.samples)))

    def frames(self) -> list[Frame]:
        out = []
        for i in range(len(self)):
            ns, nc, s = int(self.n_slots[i]), int(self.n_ch[i]), int(self.start[i])
            out.append(
                Frame(
                    int(self.flags[i]),
                    int(self.seq[i]),
                    int(self.rev[i]),
                    int(self.first_slot[i]),
                    ns,
                    nc,
                    int(self.t_us[i]),
                    self.samples[s : s + ns * nc].reshape(ns, nc),
                    int(self.skipped_before[i]),
                )
            )
        return out


def header_problem(version: int, flags: int, first_slot: int, n_slots: int, n_ch: int) -> str | None:
    """Why a header cannot be a v1 frame's (frame error key), or None if it can."""
    if version != VERSION:
        return "version"
    if (
        flags & _RESERVED
        or n_slots == 0
        or n_ch == 0
        or first_slot + n_slots > SLOTS_PER_REV
        or (flags & FLAG_TRIGGER and first_slot != 0)
        or (not flags & FLAG_SIMULTANEOUS and n_ch != 1)
    ):
        return "header"
    return None


class FrameDecoder:
    """Incremental, resynchronising frame decoder.

    Statistics (cumulative): ``frames_good``, ``frames_bad`` (candidate frames that
    failed version, header or CRC checks; ``frame_errors`` has them by reason),
    ``bytes_skipped`` (bytes that are not part of any good frame).
    """

    def __init__(self) -> None:
        self._buf = bytearray()  # bytes held back: an incomplete frame or a trailing sync byte
        self._need = 0  # held bytes needed before decoding can make progress
        self._skip_run = 0  # bytes skipped since the last good frame (already counted)
        self.frames_good = 0
        self.frames_bad = 0
        self.bytes_skipped = 0
        self.frame_errors: dict[str, int] = {}

    @property
    def pending(self) -> int:
        """Bytes held back (an incomplete frame or a trailing sync byte)."""
        return len(self._buf)

    def reset(self) -> None:
        """Forget held bytes (link dropped): they count as skipped."""
        self._skip(len(self._buf))
        self._buf = bytearray()
        self._need = 0

    def _skip(self, n: int) -> None:
        self.bytes_skipped += n
        self._skip_run += n

    def feed(self, data: bytes) -> list[Frame]:
        return self.feed_batch(data).frames()

    def feed_batch(self, data: bytes) -> FrameBatch:
        if self._buf:
            self._buf += data
            if len(self._buf) < self._need:  # the held frame is still incomplete
                return FrameBatch.empty()
            buf = bytes(self._buf)
        else:
            buf = bytes(data)
        mv = memoryview(buf)
        n = len(buf)
        find, startswith, unpack = buf.find, buf.startswith, _CHECKED.unpack_from
        starts: list[int] = []  # good frames' offsets in buf
        skips: list[tuple[int, int]] = []  # (index in starts, bytes skipped before it)
        pos = 0  # first byte not yet accounted for
        scan = 0  # where to look for the next sync
        keep = n  # first byte to hold back for the next feed
        need = 0  # bytes from ``keep`` on that a held frame needs
        while True:
            c = scan if startswith(SYNC, scan) else find(SYNC, scan)
            if c < 0:
                keep = n - 1 if n > pos and buf[-1] == _LAST_SYNC_BYTE0 else n
                break
            if c + HEADER_SIZE > n:
                keep, need = c, c + HEADER_SIZE
                break
            ver, flags, fs, ns, nch = unpack(buf, c)
            # the checks of header_problem(), inline (this loop runs once per frame)
            if (
                ver == VERSION
                and not flags & _RESERVED
                and ns
                and nch
                and fs + ns <= SLOTS_PER_REV
                and (fs == 0 or not flags & FLAG_TRIGGER)
                and (nch == 1 or flags & FLAG_SIMULTANEOUS)
            ):
                end = c + HEADER_SIZE + 2 * ns * nch + CRC_SIZE
                if end > n:
                    keep, need = c, end
                    break
                if crc_hqx(mv[c + 2 : end - 2], 0xFFFF) == buf[end - 2] | (buf[end - 1] << 8):
                    if c > pos:
                        self._skip(c - pos)
                    if self._skip_run:
                        skips.append((len(starts), self._skip_run))
                        self._skip_run = 0
                    starts.append(c)
                    pos = scan = end
                    continue
                problem = "crc"
            else:
                problem = header_problem(ver, flags, fs, ns, nch) or "header"  # the inline check failed: never None
            self.frames_bad += 1
            count(self.frame_errors, problem)
            scan = c + 1
        keep = max(keep, pos)
        if keep > pos:
            self._skip(keep - pos)
        self._buf = bytearray(mv[keep:])
        self._need = need - keep if need else 0
        if not starts:
            return FrameBatch.empty()
        self.frames_good += len(starts)
        # headers of all good frames at once: gather their 18 bytes, view as records
        p = np.array(starts, np.int64)
        h = np.frombuffer(buf, np.uint8)[p[:, None] + np.arange(HEADER_SIZE)].view(_HEADER_DTYPE)[:, 0]
        cols = [h[k].astype(np.int64) for k in ("flags", "seq", "rev", "first_slot", "n_slots", "n_ch", "t_us")]
        skipped = np.zeros(len(starts), np.int64)
        for i, k in skips:
            skipped[i] = k
        sizes = cols[4] * cols[5]
        payload = b"".join([mv[a : a + 2 * z] for a, z in zip((p + HEADER_SIZE).tolist(), sizes.tolist())])
        start = np.zeros(len(starts), np.int64)
        np.cumsum(sizes[:-1], out=start[1:])
        return FrameBatch(*cols, skipped, start, np.frombuffer(payload, "<i2").astype(np.int16, copy=False))
