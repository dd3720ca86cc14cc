"""Property tests: the decoder never raises, never hangs, never yields a revolution
that was not sent intact (compared with what was sent)."""

from __future__ import annotations

import numpy as np
from support.daq_encoder import signal, stream
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from daq.frames import FrameDecoder
from daq.revolutions import RevolutionAssembler

SETTINGS = settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def decode(data: bytes, cuts: list[int], channels: int, mode: str):
    dec, asm = FrameDecoder(), RevolutionAssembler(channels, mode)
    bounds = sorted({0, len(data), *[c % (len(data) + 1) for c in cuts]})
    parts = [asm.push_batch(dec.feed_batch(data[a:b])) for a, b in zip(bounds, bounds[1:])]
    parts.append(asm.flush())
    return dec, asm, [r for p in parts for r in p.revolutions()]


@SETTINGS
@given(
    data=st.binary(max_size=4000),
    cuts=st.lists(st.integers(0, 4000), max_size=8),
    mode=st.sampled_from(["sequential", "simultaneous"]),
)
def test_arbitrary_bytes(data, cuts, mode):
    dec, asm, revs = decode(data, cuts, 8, mode)
    assert revs == []
    assert dec.bytes_skipped + dec.pending <= len(data)


MUTATION = st.tuples(
    st.sampled_from(["flip", "delete", "insert", "drop_frame", "dup_frame"]),
    st.integers(0, 10**9),
    st.integers(0, 255),
    st.integers(1, 40),
)


@SETTINGS
@given(
    mode=st.sampled_from(["sequential", "simultaneous"]),
    layout=st.sampled_from([(8, 45), (8, 180), (4, 120), (2, 255)]),
    seq0=st.integers(0, 65535),
    rev0=st.integers(0, 2**32 - 1),
    mutations=st.lists(MUTATION, max_size=6),
    cuts=st.lists(st.integers(0, 10**6), max_size=10),
    seed=st.integers(0, 2**16),
)
def test_damaged_streams_never_yield_damaged_revolutions(mode, layout, seq0, rev0, mutations, cuts, seed):
    channels, frame_slots = layout
    if mode == "simultaneous":
        frame_slots = min(frame_slots, 90)
    n = 5
    counts = signal(n, channels, mode, noise=500, seed=seed)
    frames, meta = stream(counts, mode, frame_slots=frame_slots, seq0=seq0, rev0=rev0)
    pieces = [bytearray(f) for f in frames]
    for kind, where, value, length in mutations:
        i = where % len(pieces)
        if kind == "drop_frame":
            del pieces[i]
        elif kind == "dup_frame":  # a repeated frame breaks the seq chain; the copies are intact
            pieces.insert(i, bytearray(pieces[i]))
        elif kind == "insert":  # garbage between two frames keeps them intact
            pieces.insert(i, bytearray(np.random.default_rng(where).integers(0, 256, length, np.uint8).tobytes()))
        else:
            p = pieces[i]
            if not p:
                continue
            k = where % len(p)
            if kind == "flip":
                p[k] ^= 1 << (value % 8)
            else:
                del p[k : k + length]
    still_sent = {bytes(p) for p in pieces}  # a revolution is intact if each of its frames still is
    damaged = {m["index"] for f, m in zip(frames, meta) if f not in still_sent}
    data = b"".join(pieces)
    dec, asm, revs = decode(data, cuts, channels, mode)
    for r in revs:
        index = (r.rev - rev0) & 0xFFFFFFFF
        assert index < n and index not in damaged
        np.testing.assert_array_equal(r.counts, counts[index])
    assert len({r.rev for r in revs}) == len(revs)
    if not mutations:
        assert len(revs) == n and asm.revolutions_dropped == 0 and dec.bytes_skipped == 0
    assert dec.bytes_skipped + dec.pending <= len(data)
