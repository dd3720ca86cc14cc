"""An independent reader of the A/D byte stream, written from docs/protocols/adc-frames.md
for the simulator tests only (it shares nothing with daq/ or sim/)."""

from __future__ import annotations

import asyncio
import binascii
import os
import struct
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np


@dataclass
class RawFrame:
    flags: int
    seq: int
    rev: int
    first_slot: int
    n_slots: int
    n_ch: int
    t_us: int
    samples: np.ndarray  # int16 (n_slots, n_ch)
    offset: int  # byte offset in the stream


def parse(buf: bytes):
    """All CRC-valid frames in buf; returns (frames, bad_candidates, leftover_index)."""
    frames, bad, i = [], 0, 0
    while True:
        j = buf.find(b"\xa5\x5a", i)
        if j < 0 or j + 20 > len(buf):
            return frames, bad, (j if j >= 0 else max(len(buf) - 1, 0))
        version, flags, seq, rev, first, n_slots, n_ch, t_us = struct.unpack_from("<BBHIHBBI", buf, j + 2)
        size = 18 + 2 * n_slots * n_ch + 2
        if version != 1 or n_slots == 0 or n_ch == 0:
            i = j + 1
            continue
        if j + size > len(buf):
            return frames, bad, j
        body = buf[j + 2 : j + size - 2]
        (crc,) = struct.unpack_from("<H", buf, j + size - 2)
        if binascii.crc_hqx(body, 0xFFFF) != crc:
            bad += 1
            i = j + 1
            continue
        samples = np.frombuffer(buf, "<i2", n_slots * n_ch, j + 18).reshape(n_slots, n_ch)
        frames.append(RawFrame(flags, seq, rev, first, n_slots, n_ch, t_us, samples.copy(), j))
        i = j + size


def revolutions(frames, *, channels=8):
    """Complete revolutions: (rev, t_us, counts (360, n_ch)) from a TRIGGER frame on,
    contiguous slots, one rev number, consecutive seq, no OVERRUN."""
    out, cur = [], None
    prev_seq = None
    for f in frames:
        gap = prev_seq is not None and f.seq != (prev_seq + 1) & 0xFFFF
        prev_seq = f.seq
        if f.flags & 0x01:
            cur = {"rev": f.rev, "t_us": f.t_us, "parts": [f.samples], "next": f.n_slots}
            if f.flags & 0x02 or f.first_slot != 0:
                cur = None
        elif cur is not None:
            if gap or f.flags & 0x02 or f.rev != cur["rev"] or f.first_slot != cur["next"]:
                cur = None
                continue
            cur["parts"].append(f.samples)
            cur["next"] += f.n_slots
        if cur is not None and cur["next"] == 360:
            out.append((cur["rev"], cur["t_us"], np.concatenate(cur["parts"])))
            cur = None
    return out


def channel_samples(counts: np.ndarray, k: int, channels: int = 8, mode: str = "sequential"):
    """(slots, counts) of channel k in one revolution."""
    if mode == "sequential":
        slots = np.arange(k, 360, channels)
        return slots, counts[slots, 0].astype(float)
    return np.arange(360), counts[:, k].astype(float)


def fundamental(values: np.ndarray, slots: np.ndarray) -> complex:
    """q_bar with q = mean + Re(q_bar e^{i theta}), theta = 2 pi slot / 360 (uniform full circle)."""
    theta = 2 * np.pi * slots / 360.0
    return complex(2.0 / len(values) * np.sum(values * np.exp(-1j * theta)))


async def read_tcp(
    port: int,
    *,
    seconds: float | None = None,
    min_revs: int | None = None,
    until: Callable[[bytes], bool] | None = None,
    timeout: float = 20.0,
    channels: int = 8,
) -> bytes:
    """Bytes from the TCP serial device server, for `seconds`, until min_revs complete revolutions
    or until `until(bytes so far)` is true; `timeout` s at most."""
    reader, writer = await asyncio.open_connection("127.0.0.1", port)
    buf = bytearray()
    t0 = time.monotonic()
    try:
        while time.monotonic() - t0 < timeout:
            try:
                chunk = await asyncio.wait_for(reader.read(1 << 16), 0.5)
            except asyncio.TimeoutError:
                chunk = b""
            buf += chunk
            if seconds is not None and time.monotonic() - t0 >= seconds:
                break
            if min_revs is not None and len(revolutions(parse(bytes(buf))[0], channels=channels)) >= min_revs:
                break
            if until is not None and chunk and until(bytes(buf)):
                break
            if chunk == b"" and reader.at_eof():
                break
    finally:
        writer.close()
    return bytes(buf)


async def read_pty(path: str, *, min_revs: int, timeout: float = 20.0, channels: int = 8) -> bytes:
    """Bytes from the board's pty until min_revs complete revolutions arrived."""
    import termios
    import tty

    fd = os.open(path, os.O_RDONLY | os.O_NOCTTY | os.O_NONBLOCK)
    tty.setraw(fd)
    termios.tcflush(fd, termios.TCIFLUSH)
    buf = bytearray()
    t0 = time.monotonic()
    try:
        while time.monotonic() - t0 < timeout:
            try:
                buf += os.read(fd, 1 << 16)
            except BlockingIOError:
                await asyncio.sleep(0.01)
                continue
            if len(revolutions(parse(bytes(buf))[0], channels=channels)) >= min_revs:
                break
    finally:
        os.close(fd)
    return bytes(buf)
