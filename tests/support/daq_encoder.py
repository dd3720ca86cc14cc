"""A small A/D board frame encoder for the daq tests, written from the spec
(docs/protocols/adc-frames.md) independently of daq.frames."""

from __future__ import annotations

import struct
from binascii import crc_hqx

import numpy as np

TRIGGER, OVERRUN, SIMULTANEOUS = 1, 2, 4


def frame(flags: int, seq: int, rev: int, first_slot: int, samples: np.ndarray, t_us: int) -> bytes:
    """samples: int16 (n_slots, n_ch), slot-major."""
    samples = np.asarray(samples, np.int16)
    n_slots, n_ch = samples.shape
    body = (
        struct.pack("<BBHIHBBI", 1, flags, seq & 0xFFFF, rev & 0xFFFFFFFF, first_slot, n_slots, n_ch, t_us & 0xFFFFFFFF)
        + samples.astype("<i2").tobytes()
    )
    return b"\xa5\x5a" + body + struct.pack("<H", crc_hqx(body, 0xFFFF))


def slot_samples(counts: np.ndarray, mode: str) -> np.ndarray:
    """(C, S) per-channel counts -> (360, n_ch) slot-major board order."""
    c = counts.shape[0]
    if mode == "sequential":
        out = np.empty(360, np.int16)
        for k in range(c):
            out[k::c] = counts[k]
        return out[:, None]
    return counts.T.copy()


def signal(
    n_revs: int, channels: int, mode: str, *, phasors=None, dc=None, noise=0.0, harmonic2=0.0, seed=0
) -> np.ndarray:
    """Counts (R, C, S): dc + Re(q e^{i theta}) + harmonic2 * cos(2 theta) + noise,
    theta = 2 pi slot / 360 at each channel's own slots."""
    rng = np.random.default_rng(seed)
    if phasors is None:
        phasors = (
            1000 * np.exp(1j * np.linspace(0, 2 * np.pi, channels, endpoint=False)) * (1 + np.arange(channels) / 4)
        )
    if dc is None:
        dc = 50.0 * np.arange(channels)
    s = 360 // channels if mode == "sequential" else 360
    if mode == "sequential":
        slots = np.arange(360).reshape(s, channels).T
    else:
        slots = np.tile(np.arange(360), (channels, 1))
    theta = 2 * np.pi * slots / 360
    base = (
        np.asarray(dc)[:, None]
        + np.real(np.asarray(phasors)[:, None] * np.exp(1j * theta))
        + harmonic2 * np.cos(2 * theta)
    )
    x = base[None] + noise * rng.standard_normal((n_revs, channels, s))
    return np.clip(np.round(x), -32768, 32767).astype(np.int16)


def stream(
    counts: np.ndarray,
    mode: str,
    *,
    frame_slots: int = 45,
    seq0: int = 0,
    rev0: int = 0,
    t0: int = 0,
    period_us: int = 80_000,
    flags_extra=None,
) -> tuple[list[bytes], list[dict]]:
    """Frames of revolutions counts (R, C, S). Returns (frame bytes list, frame metadata)."""
    frames, meta = [], []
    seq = seq0
    for r, rc in enumerate(counts):
        slots = slot_samples(rc, mode)
        t_rev = t0 + r * period_us
        for fs in range(0, 360, frame_slots):
            ns = min(frame_slots, 360 - fs)
            flags = (TRIGGER if fs == 0 else 0) | (SIMULTANEOUS if mode == "simultaneous" else 0)
            if flags_extra:
                flags |= flags_extra(r, fs)
            t = t_rev + int(fs * period_us / 360)
            frames.append(frame(flags, seq, rev0 + r, fs, slots[fs : fs + ns], t))
            meta.append({"rev": (rev0 + r) & 0xFFFFFFFF, "index": r, "first_slot": fs, "seq": seq & 0xFFFF})
            seq += 1
    return frames, meta
