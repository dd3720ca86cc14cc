"""The clocked A/D board of docs/protocols/adc-frames.md: quantisation and frame encoding.

Written from the spec only (independent of daq/). Frame layout, little-endian:
sync A5 5A | version u8 | flags u8 | seq u16 | rev u32 | first_slot u16 |
n_slots u8 | n_ch u8 | t_us u32 | int16 samples slot-major | crc u16, the
CRC-16/CCITT-FALSE over version..last sample byte (binascii.crc_hqx(body, 0xFFFF)).

Slots are addressed by a global slot index g (g // 360 revolutions since the
board started, slot g % 360). A frame never spans two revolutions and frames
start at multiples of ``frame_slots`` inside a revolution (the first frame
after start-up may start anywhere).

Without a fault switched on, a block of BLOCK_FRAMES frames or more is built at once in one
array (the CRCs one binascii call per frame); with a fault, or fewer frames (a live tick at a
low speed-up), frame by frame, the same bytes either way
(tests/sim/test_sim_adc_encode.py).
"""

from __future__ import annotations

import binascii
import struct

import numpy as np

SYNC = b"\xa5\x5a"
VERSION = 1
TRIGGER, OVERRUN, SIMULTANEOUS = 0x01, 0x02, 0x04
SLOTS = 360
_HEADER = struct.Struct("<BBHIHBBI")  # version .. t_us (16 bytes)
_CRC = struct.Struct("<H")
#: sync .. t_us of a frame (18 bytes, 9 little-endian words); the sync bytes A5 5A as one word
_HEAD = np.dtype(
    [("sync", "<u2"), ("version", "u1"), ("flags", "u1"), ("seq", "<u2"), ("rev", "<u4")]
    + [("first_slot", "<u2"), ("n_slots", "u1"), ("n_ch", "u1"), ("t_us", "<u4")]
)
_SYNC_WORD = int.from_bytes(SYNC, "little")
#: frames from which a block is encoded at once: its numpy calls cost about 35 µs whatever the
#: frames, one frame alone 1.6 µs (8 ch sequential) to 3.3 µs (simultaneous): even at 30 and 55 frames
BLOCK_FRAMES = 40


def channel_slots(channels: int, mode: str, first: int = 0) -> tuple[slice, ...]:
    """Each channel's conversions among consecutive slots from global slot `first` (a revolution's
    SLOTS from 0 by default), as a slice of them: sequential scan, slot g converts channel g mod C
    (docs/protocols/adc-frames.md; C divides SLOTS); simultaneous, every channel at every slot."""
    if mode == "sequential":
        return tuple(slice((k - first) % channels, None, channels) for k in range(channels))
    return (slice(None),) * channels


class AdcBoard:
    """Encoder and counters of the board, with its fault switches.

    Faults (set by the rig): ``corrupt`` frames to corrupt, ``drop`` frames to
    lose in the FIFO (seq still counts, the next frame carries OVERRUN),
    ``missed_triggers`` trigger pulses to miss (no TRIGGER flag, rev not
    incremented), ``stalled`` board clock frozen.
    """

    def __init__(
        self,
        *,
        channels: int = 8,
        mode: str = "sequential",
        frame_slots: int = 45,
        gains=None,
        offsets=None,
        rng: np.random.Generator | None = None,
    ):
        if mode == "simultaneous":
            if not 1 <= channels <= 255:  # n_ch = C is a u8
                raise ValueError(f"channel count {channels} outside 1..255 (simultaneous mode)")
        elif not 1 <= channels <= SLOTS or SLOTS % channels:  # slot s converts channel s mod C
            raise ValueError(f"channel count {channels} does not divide 360 (sequential mode)")
        if not 1 <= frame_slots <= 255:
            raise ValueError(f"frame_slots must be 1..255, got {frame_slots}")
        self.channels = channels
        self.mode = mode
        self.simultaneous = mode == "simultaneous"
        self.frame_slots = frame_slots
        self.gains = np.asarray(gains if gains is not None else [1.0] * channels, dtype=float)
        self.offsets = np.asarray(offsets if offsets is not None else [0.0] * channels, dtype=float)
        self.rng = rng or np.random.default_rng()
        self.seq = 0
        self.rev = 0
        self.overrun = False
        self.corrupt = 0
        self.drop = 0
        self.missed_triggers = 0
        self.stalled = False
        self._stall_us = 0
        self.frames_sent = 0
        self.frames_lost = 0

    # -------------------------------------------------------------- geometry
    def boundary_before(self, g: int) -> int:
        """Largest frame boundary <= g (global slot index)."""
        s = g % SLOTS
        return g - s + (s // self.frame_slots) * self.frame_slots

    def _frames(self, g0: int, g1: int):
        """(start, end) global slot ranges of the frames covering [g0, g1)."""
        g = g0
        while g < g1:
            s = g % SLOTS
            end = min(g - s + min((s // self.frame_slots + 1) * self.frame_slots, SLOTS), g1)
            yield g, end
            g = end

    def channel_of_slot(self, g: np.ndarray) -> np.ndarray:
        """Channel converted at each global slot in sequential mode (slot mod C, as `channel_slots`)."""
        return (np.asarray(g) % SLOTS) % self.channels

    # -------------------------------------------------------------- encoding
    def quantize(self, values: np.ndarray, channel: np.ndarray | int | None = None) -> np.ndarray:
        """Engineering values -> int16 counts (round, saturate).

        values: (n,) with ``channel`` the channel of each sample (sequential),
        or (n, C) for all channels (simultaneous)."""
        if channel is None:
            counts = (values - self.offsets) / self.gains
        else:
            counts = (values - self.offsets[channel]) / self.gains[channel]
        return np.clip(np.rint(counts), -32768, 32767).astype("<i2")

    def _trigger(self, start: int) -> int:
        if start % SLOTS:
            return 0
        if self.missed_triggers > 0:
            self.missed_triggers -= 1
            return 0
        self.rev = (self.rev + 1) & 0xFFFFFFFF
        return TRIGGER

    def encode(self, g0: int, counts: np.ndarray, t: np.ndarray) -> bytes:
        """Frames for the slots [g0, g0 + len(counts)).

        counts: int16 (n,) sequential or (n, C) simultaneous; t: simulated
        time (s) of each slot, the board clock of a frame is t at its first slot.
        Without a fault switched on, from BLOCK_FRAMES frames on, every frame at once (`_encode_block`).
        """
        if self.corrupt > 0 or self.drop > 0 or self.missed_triggers > 0 or self.stalled:
            return self._encode_frames(g0, counts, t)
        g1 = g0 + len(counts)
        frames = self._starts_before(g1) - self._starts_before(g0) + (g0 != self.boundary_before(g0))
        if frames < BLOCK_FRAMES:
            return self._encode_frames(g0, counts, t)
        return self._encode_block(g0, counts, t)

    def _frame_starts(self, g0: int, g1: int) -> np.ndarray:
        """Global slots (int64) where the frames covering [g0, g1) start (as `_frames`)."""
        per_rev = -(-SLOTS // self.frame_slots)
        i = np.arange(self._starts_before(g0), self._starts_before(g1), dtype=np.int64)
        starts = (i // per_rev) * SLOTS + (i % per_rev) * self.frame_slots
        return starts if g0 == self.boundary_before(g0) else np.concatenate([[g0], starts])

    def _encode_block(self, g0: int, counts: np.ndarray, t: np.ndarray) -> bytes:
        """`encode` without faults: the frames of the block as one array of 16-bit words (a
        frame's 20 bytes of sync, header and CRC are 10 words), the CRCs one call per frame."""
        n = len(counts)
        if n == 0:
            return b""
        n_ch = self.channels if self.simultaneous else 1
        words = np.ascontiguousarray(counts, dtype="<i2").view("<u2").reshape(-1)
        starts = self._frame_starts(g0, g0 + n)
        nf = len(starts)
        lengths = np.empty_like(starts)  # slots per frame
        lengths[:-1], lengths[-1] = starts[1:] - starts[:-1], g0 + n - starts[-1]
        first_slot = starts % SLOTS
        trigger = first_slot == 0
        head = np.zeros(nf, _HEAD)
        head["sync"], head["version"], head["n_ch"] = _SYNC_WORD, VERSION, n_ch
        head["flags"] = trigger.view(np.uint8) * TRIGGER | (SIMULTANEOUS if self.simultaneous else 0)
        if self.overrun:
            head["flags"][0] |= OVERRUN
            self.overrun = False
        head["seq"] = (self.seq + np.arange(nf)) & 0xFFFF
        head["rev"] = (self.rev + np.cumsum(trigger)) & 0xFFFFFFFF
        head["first_slot"], head["n_slots"] = first_slot, lengths
        head["t_us"] = (np.asarray(t)[starts - g0] * 1e6).astype(np.int64) & 0xFFFFFFFF
        self.seq = (self.seq + nf) & 0xFFFF
        self.rev = int(head["rev"][-1])
        self._stall_us = int(head["t_us"][-1])
        first = 10 * np.arange(nf) + n_ch * (starts - g0)  # word of each frame's sync
        crc_at = first + 9 + n_ch * lengths
        out = np.empty(10 * nf + len(words), "<u2")
        framing = np.zeros(len(out), bool)  # the words of sync, header and CRC
        framing[first[:, None] + np.arange(9)] = framing[crc_at] = True
        out[framing] = np.concatenate([head.view("<u2").reshape(nf, 9), np.zeros((nf, 1), "<u2")], axis=1).ravel()
        out[~framing] = words
        body = out.data.cast("B")  # bytes
        out[crc_at] = [
            binascii.crc_hqx(body[a:b], 0xFFFF) for a, b in zip((2 * first + 2).tolist(), (2 * crc_at).tolist())
        ]
        self.frames_sent += nf
        return out.tobytes()

    def _encode_frames(self, g0: int, counts: np.ndarray, t: np.ndarray) -> bytes:
        """`encode` one frame at a time, with the faults (a corrupted byte, a frame lost, a
        trigger missed, the clock stalled)."""
        n = len(counts)
        counts = np.ascontiguousarray(counts, dtype="<i2")
        n_ch = self.channels if self.simultaneous else 1
        mode_flag = SIMULTANEOUS if self.simultaneous else 0
        t_us = (np.asarray(t) * 1e6).astype(np.int64) & 0xFFFFFFFF
        out = []
        for start, end in self._frames(g0, g0 + n):
            flags = mode_flag | self._trigger(start)
            seq = self.seq
            self.seq = (self.seq + 1) & 0xFFFF
            if self.drop > 0:
                self.drop -= 1
                self.overrun = True
                self.frames_lost += 1
                continue
            if self.overrun:
                flags |= OVERRUN
                self.overrun = False
            if self.stalled:
                stamp = self._stall_us
            else:
                stamp = int(t_us[start - g0])
                self._stall_us = stamp
            body = (
                _HEADER.pack(VERSION, flags, seq, self.rev, start % SLOTS, end - start, n_ch, stamp)
                + counts[start - g0 : end - g0].tobytes()
            )
            frame = SYNC + body + _CRC.pack(binascii.crc_hqx(body, 0xFFFF))
            if self.corrupt > 0:
                self.corrupt -= 1
                buf = bytearray(frame)
                pos = int(self.rng.integers(2, len(buf)))
                buf[pos] ^= 1 << int(self.rng.integers(0, 8))
                frame = bytes(buf)
            out.append(frame)
            self.frames_sent += 1
        return b"".join(out)

    def _starts_before(self, g: int) -> int:
        """Number of frame starts at global slots [0, g)."""
        per_rev = -(-SLOTS // self.frame_slots)
        return (g // SLOTS) * per_rev + -(-(g % SLOTS) // self.frame_slots)

    def lose(self, g0: int, g1: int) -> None:
        """The slots [g0, g1) were converted but lost (nobody read the FIFO):
        counters advance as if their frames had been made; OVERRUN follows."""
        if g1 <= g0:
            return
        n = self._starts_before(g1) - self._starts_before(g0) + (g0 != self.boundary_before(g0))
        triggers = -(-g1 // SLOTS) - -(-g0 // SLOTS)
        missed = min(self.missed_triggers, triggers)
        self.missed_triggers -= missed
        self.rev = (self.rev + triggers - missed) & 0xFFFFFFFF
        self.seq = (self.seq + n) & 0xFFFF
        self.frames_lost += n
        self.overrun = True
