"""A deliberately naive reference reader for the daq tests: what was on the wire.

Taps the simulator's byte stream and parses it one frame at a time in plain
Python (spec: docs/protocols/adc-frames.md), to tell which revolutions went out
intact and what their samples were. Independent of daq.frames/daq.revolutions.
"""

from __future__ import annotations

import struct
from binascii import crc_hqx

import numpy as np


class WireTap:
    """Wraps ``rig.adc_server.send`` and keeps every byte the board sent."""

    def __init__(self, rig) -> None:
        self.chunks: list[bytes] = []
        send = rig.adc_server.send

        def tapped(data: bytes) -> None:
            self.chunks.append(bytes(data))
            send(data)

        rig.adc_server.send = tapped

    def frames(self) -> list[tuple]:
        """(flags, seq, rev, first_slot, samples (n_slots, n_ch)) of every CRC-valid frame."""
        buf = b"".join(self.chunks)
        out, i = [], 0
        while i + 20 <= len(buf):
            if buf[i : i + 2] != b"\xa5\x5a":
                i += 1
                continue
            ver, flags, seq, rev, fs, ns, nch, t = struct.unpack("<BBHIHBBI", buf[i + 2 : i + 18])
            end = i + 20 + 2 * ns * nch
            if (
                ver == 1
                and end <= len(buf)
                and crc_hqx(buf[i + 2 : end - 2], 0xFFFF) == struct.unpack("<H", buf[end - 2 : end])[0]
            ):
                out.append((flags, seq, rev, fs, np.frombuffer(buf[i + 18 : end - 2], "<i2").reshape(ns, nch)))
                i = end
            else:
                i += 1
        return out

    def intact_revolutions(self) -> dict[int, list[np.ndarray]]:
        """rev -> slot-major samples (360, n_ch) of each revolution that went out
        whole: TRIGGER frame, slots 0..359 contiguous, consecutive seq, one rev
        number, no OVERRUN (a list: the rev number repeats after missed triggers)."""
        out: dict[int, list[np.ndarray]] = {}
        cur = None
        for flags, seq, rev, fs, samples in self.frames():
            if flags & 1 and not flags & 2:
                cur = (rev, seq, [samples], fs + len(samples))
                continue
            if cur is None:
                continue
            r, s, parts, nxt = cur
            if rev == r and seq == (s + 1) & 0xFFFF and fs == nxt and not flags & 3:
                cur = (r, seq, parts + [samples], nxt + len(samples))
                if cur[3] == 360:
                    out.setdefault(r, []).append(np.concatenate(cur[2]))
                    cur = None
            else:
                cur = None
        return out
