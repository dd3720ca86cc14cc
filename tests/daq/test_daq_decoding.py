"""Frame decoder, revolution assembler and averager on frames from an independent encoder."""

from __future__ import annotations

import numpy as np
import pytest
from support.daq_encoder import OVERRUN, SIMULTANEOUS, TRIGGER, frame, signal, slot_samples, stream

from daq.averager import StreamingAverager
from daq.frames import FrameDecoder
from daq.adc_mode import AdcMode
from daq.revolutions import RevolutionAssembler
from reduction.fourier import phasor


def run(data: bytes, channels=8, mode="sequential", chunk=997):
    dec, asm = FrameDecoder(), RevolutionAssembler(channels, mode)
    parts = [asm.push_batch(dec.feed_batch(data[i : i + chunk])) for i in range(0, len(data), chunk)]
    parts.append(asm.flush())
    revs = [r for p in parts for r in p.revolutions()]
    return dec, asm, revs


def check_intact(revs, counts, rev0=0):
    for r in revs:
        np.testing.assert_array_equal(r.counts, counts[(r.rev - rev0) & 0xFFFFFFFF])


@pytest.mark.parametrize(
    "mode,channels,frame_slots",
    [
        ("sequential", 8, 45),
        ("sequential", 8, 180),
        ("sequential", 4, 120),
        ("simultaneous", 8, 45),
        ("simultaneous", 3, 72),
    ],
)
def test_clean_stream_all_revolutions_exact(mode, channels, frame_slots):
    counts = signal(12, channels, mode, noise=3)
    frames, _ = stream(counts, mode, frame_slots=frame_slots)
    dec, asm, revs = run(b"".join(frames), channels, mode)
    assert [r.rev for r in revs] == list(range(12))
    check_intact(revs, counts)
    assert dec.frames_good == len(frames) and dec.frames_bad == 0 and dec.bytes_skipped == 0
    assert asm.revolutions_dropped == 0 and asm.revolutions_good == 12
    assert [r.period_s for r in revs[:-1]] == [pytest.approx(0.08, abs=1e-6)] * 11
    assert revs[-1].period_s is None  # flushed: no next trigger


def test_wraps_of_seq_rev_and_clock():
    counts = signal(6, 8, "sequential")
    frames, _ = stream(counts, "sequential", seq0=65530, rev0=2**32 - 3, t0=2**32 - 100_000, period_us=40_000)
    dec, asm, revs = run(b"".join(frames))
    assert [r.rev for r in revs] == [2**32 - 3, 2**32 - 2, 2**32 - 1, 0, 1, 2]
    assert asm.revolutions_dropped == 0
    assert all(r.period_s == pytest.approx(0.04) for r in revs[:-1])


def test_byte_by_byte_equals_one_feed():
    counts = signal(3, 8, "simultaneous")
    data = b"".join(stream(counts, "simultaneous")[0])
    _, _, a = run(data, mode="simultaneous", chunk=1)
    _, _, b = run(data, mode="simultaneous", chunk=len(data))
    assert len(a) == len(b) == 3
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x.counts, y.counts)


def test_sync_pattern_inside_payload():
    counts = np.full((4, 8, 45), 0x5AA5, np.int16)  # bytes A5 5A on the wire
    dec, asm, revs = run(b"".join(stream(counts, "sequential")[0]))
    assert len(revs) == 4 and dec.bytes_skipped == 0
    check_intact(revs, counts)


def test_frame_api_and_flags():
    s = np.arange(90, dtype=np.int16).reshape(45, 2)
    f = FrameDecoder().feed(frame(TRIGGER | SIMULTANEOUS | OVERRUN, 7, 9, 0, s, 123))
    assert len(f) == 1
    f = f[0]
    assert (f.trigger, f.overrun, f.simultaneous) == (True, True, True)
    assert (f.seq, f.rev, f.first_slot, f.n_slots, f.n_ch, f.t_us) == (7, 9, 0, 45, 2, 123)
    np.testing.assert_array_equal(f.samples, s)


def test_header_checks():
    good = frame(TRIGGER, 0, 0, 0, np.zeros((45, 1)), 0)
    bad_version = good[:2] + b"\x02" + good[3:]
    reserved_flag = frame(TRIGGER | 0x10, 0, 0, 0, np.zeros((45, 1)), 0)
    past_360 = frame(0, 0, 0, 350, np.zeros((20, 1)), 0)
    seq_multi = frame(0, 0, 0, 0, np.zeros((20, 2)), 0)  # sequential with 2 samples per slot
    dec = FrameDecoder()
    assert dec.feed(bad_version + reserved_flag + past_360 + seq_multi + good)[0].n_slots == 45
    assert dec.frame_errors == {"version": 1, "header": 3}
    assert dec.bytes_skipped == len(bad_version + reserved_flag + past_360 + seq_multi)


def faulty(mutate, mode="sequential", n=8):
    counts = signal(n, 8, mode, noise=2)
    frames, meta = stream(counts, mode)
    frames = mutate(frames, meta)
    return counts, run(b"".join(frames), 8, mode)


def test_lost_frame_is_a_seq_gap():
    counts, (dec, asm, revs) = faulty(lambda f, m: f[:20] + f[21:])  # rev 2, slots 180..224
    assert [r.rev for r in revs] == [0, 1, 3, 4, 5, 6, 7]
    assert asm.drop_reasons == {"seq_gap": 1} and asm.revolutions_dropped == 1
    assert revs[1].period_s == pytest.approx(0.08)  # rev 2's trigger was good
    check_intact(revs, counts)


def test_corrupt_frame_counted_and_dropped():
    def flip(f, m):
        f = list(f)
        f[19] = f[19][:30] + bytes([f[19][30] ^ 0x10]) + f[19][31:]
        return f

    counts, (dec, asm, revs) = faulty(flip)
    assert 2 not in [r.rev for r in revs] and len(revs) == 7
    assert dec.frame_errors == {"crc": 1} and dec.frames_bad == 1
    assert dec.bytes_skipped >= 1
    assert asm.drop_reasons == {"corrupt": 1}
    check_intact(revs, counts)


@pytest.mark.parametrize("how", ["corrupt", "seq_gap"])
def test_revolutions_whose_every_frame_was_lost_are_counted(how):
    """20 frames of 45 slots lost from rev 2's slot 180 on: rev 2 broken, revs 3 and 4 never
    seen at all (their count comes from the rev numbers' gap when rev 5 arrives)."""

    def lose(f, m):
        f = list(f)
        if how == "seq_gap":
            return f[:20] + f[40:]
        for i in range(20, 40):
            f[i] = f[i][:30] + bytes([f[i][30] ^ 0x10]) + f[i][31:]
        return f

    counts, (dec, asm, revs) = faulty(lose, n=10)
    assert [r.rev for r in revs] == [0, 1, 5, 6, 7, 8, 9]
    assert asm.revolutions_dropped == 3 and asm.drop_reasons == {how: 3}
    assert asm.revolutions_good + asm.revolutions_dropped == 10
    check_intact(revs, counts)


def test_overrun_flag_drops_its_revolution():
    counts = signal(6, 8, "sequential")
    frames, _ = stream(counts, "sequential", flags_extra=lambda r, fs: OVERRUN if (r, fs) in ((1, 90), (3, 0)) else 0)
    dec, asm, revs = run(b"".join(frames))
    assert [r.rev for r in revs] == [0, 2, 4, 5]
    assert asm.drop_reasons == {"overrun": 2}


def test_missing_trigger_flag():
    counts = signal(6, 8, "sequential")
    frames, _ = stream(counts, "sequential", flags_extra=None)
    # rebuild rev 2's first frame without the TRIGGER flag
    frames[16] = frame(0, 16, 2, 0, slot_samples(counts[2], "sequential")[:45], 2 * 80_000)
    dec, asm, revs = run(b"".join(frames))
    assert [r.rev for r in revs] == [0, 1, 3, 4, 5]
    assert revs[1].period_s is None  # its next trigger never came
    assert asm.drop_reasons == {"missing_trigger": 1}


def test_rev_mismatch_and_early_trigger():
    def mutate(f, m):
        f = list(f)
        z = np.zeros((45, 1))
        f[12] = frame(0, 12, 99, 180, z, 120_000)  # rev 1, wrong rev number
        f[26] = frame(TRIGGER, 26, 4, 0, z, 260_000)  # a trigger inside rev 3 (slot 90)
        return f

    counts, (dec, asm, revs) = faulty(mutate)
    # rev 1: broken by a frame with rev 99 (its fragments are rev 1's: counted once);
    # rev 3: cut short by a stray trigger frame, whose one-frame "revolution 4" is dropped too;
    # the real rev 4 that follows is intact
    assert [r.rev for r in revs] == [0, 2, 4, 5, 6, 7]
    assert asm.drop_reasons == {"rev_mismatch": 2, "incomplete": 1} and asm.revolutions_dropped == 3
    check_intact(revs, counts)


@pytest.mark.parametrize("chunk", [1, 113, 997, 1 << 20])
@pytest.mark.parametrize(
    "where,lost,reason",
    [
        (12, None, "rev_mismatch"),  # rev 1, slot 180: rev 99 on one frame, rev 1 again after it
        (9, None, "rev_mismatch"),  # rev 1, slot 45: right after the trigger frame
        (15, None, "rev_mismatch"),  # rev 1, slot 315: its last frame
        (12, 8, "seq_gap"),  # rev 1's trigger frame lost too: the first reason is the seq gap
    ],
)
def test_revolution_renumbered_mid_revolution_is_dropped_once(where, lost, reason, chunk):
    """One revolution whose rev number changes mid-revolution (no frame lost in between) is
    one dropped revolution, under the first reason found, in whatever pieces the bytes come."""
    counts = signal(5, 8, "sequential", noise=2)
    frames, meta = stream(counts, "sequential")
    m = meta[where]
    frames[where] = frame(
        0,
        m["seq"],
        99,
        m["first_slot"],
        slot_samples(counts[1], "sequential")[m["first_slot"] : m["first_slot"] + 45],
        80_000 + m["first_slot"] * 80_000 // 360,
    )
    if lost is not None:
        del frames[lost]
    dec, asm, revs = run(b"".join(frames), chunk=chunk)
    assert [r.rev for r in revs] == [0, 2, 3, 4]
    assert asm.drop_reasons == {reason: 1}
    assert asm.revolutions_dropped == 1 and asm.revolutions_good == 4
    assert dec.frames_good == len(frames) and dec.frames_bad == 0
    check_intact(revs, counts)


def test_garbage_between_frames_keeps_revolutions():
    def mutate(f, m):
        return [x + (b"\xa5\x5a\x01garbage" if i % 5 == 2 else b"") for i, x in enumerate(f)]

    counts, (dec, asm, revs) = faulty(mutate)
    assert len(revs) == 8 and asm.revolutions_dropped == 0
    assert dec.bytes_skipped == 10 * len([i for i in range(64) if i % 5 == 2])
    check_intact(revs, counts)


def test_mode_mismatch():
    counts = signal(4, 8, "simultaneous")
    dec, asm, revs = run(b"".join(stream(counts, "simultaneous")[0]), 8, "sequential")
    assert revs == [] and asm.drop_reasons == {"mode_mismatch": 4}


def test_the_scan_mode_is_an_adc_mode_given_as_member_or_word():
    assert RevolutionAssembler(8, "simultaneous").mode is AdcMode.SIMULTANEOUS
    assert RevolutionAssembler(8, AdcMode.SEQUENTIAL).mode is AdcMode.SEQUENTIAL
    with pytest.raises(ValueError, match="mode must be 'sequential' or 'simultaneous', not 'parallel'"):
        RevolutionAssembler(8, "parallel")


@pytest.mark.parametrize("chunk", [50, 997, 100_000])
def test_start_mid_revolution_is_not_a_fault(chunk):
    counts = signal(4, 8, "sequential")
    frames, _ = stream(counts, "sequential")
    dec, asm, revs = run(b"".join(frames[3:])[7:], chunk=chunk)
    assert [r.rev for r in revs] == [1, 2, 3]
    assert asm.revolutions_dropped == 0 and asm.frames_discarded == 4


def test_reset_discards_revolution_in_progress():
    counts = signal(4, 8, "sequential")
    data = b"".join(stream(counts, "sequential")[0])
    dec, asm = FrameDecoder(), RevolutionAssembler()
    first = asm.push_batch(dec.feed_batch(data[: len(data) // 2 + 100]))
    asm.reset()
    rest = asm.push_batch(dec.feed_batch(data[len(data) // 2 + 100 :]))
    assert list(first.rev) == [0] and list(rest.rev) == [2] and asm.revolutions_dropped == 0


def test_sequential_channels_carry_their_own_angles():
    """Channel k is sampled k degrees after the trigger: its phasor must come out exact."""
    ph = 800 * np.exp(1j * np.deg2rad([0, 30, 60, 90, 120, 150, 180, 210]))
    counts = signal(50, 8, "sequential", phasors=ph, dc=np.zeros(8))
    frames, _ = stream(counts, "sequential")
    frames += stream(counts[:1], "sequential", seq0=len(frames), rev0=50, t0=50 * 80_000)[0]
    _, asm, revs = run(b"".join(frames))
    avg = StreamingAverager(50)
    blocks = [b for r in revs[:50] for b in [avg.push(r)] if b is not None]
    assert len(blocks) == 1
    b = blocks[0]
    np.testing.assert_allclose(b.phasors, ph, atol=0.6)  # rounding to counts only
    assert np.max(np.abs(np.angle(b.phasors / ph, deg=True))) < 0.05
    assert b.orbit_speed == pytest.approx(2 * np.pi / 0.08)
    assert b.record_phasors.shape == (50, 8)
    np.testing.assert_allclose(b.theta[3, :2], np.deg2rad([3, 11]))


def test_averager_calibration_residual_and_blocks():
    counts = signal(30, 4, "simultaneous", noise=20, harmonic2=100, seed=3)
    frames, _ = stream(counts, "simultaneous")
    _, _, revs = run(b"".join(frames), 4, "simultaneous")
    gains, offsets = [0.1, 0.2, 1.0, 5e-9], [1.0, 0.0, -2.0, 0.0]
    avg = StreamingAverager(10, gains, offsets)
    blocks = [b for r in revs for b in [avg.push(r)] if b is not None]
    assert len(blocks) == 3 and avg.count == 0
    b = blocks[1]
    raw = counts[10:20].astype(float).mean(axis=0)
    np.testing.assert_allclose(b.mean, raw * np.array(gains)[:, None] + np.array(offsets)[:, None])
    np.testing.assert_allclose(b.phasors, phasor(raw, b.theta) * gains)
    np.testing.assert_allclose(b.record_phasors, phasor(counts[10:20], b.theta) * gains)
    np.testing.assert_allclose(b.dc, raw.mean(axis=1) * gains + offsets)
    # residual = the 2nd harmonic (100/sqrt 2) plus averaged noise (20/sqrt(10))
    expected = np.hypot(100 / np.sqrt(2), 20 / np.sqrt(10)) * np.array(gains)
    np.testing.assert_allclose(b.rms_residual, expected, rtol=0.1)
    np.testing.assert_array_equal(b.revs, np.arange(10, 20))


def test_averager_rejects_bad_calibration():
    _, _, revs = run(b"".join(stream(signal(2, 8, "sequential"), "sequential")[0]))
    with pytest.raises(ValueError, match="gains has 2 values for 8 channels"):
        StreamingAverager(2, gains=[1.0, 2.0]).push(revs[0])


def test_stalled_board_clock_drops_revolutions_without_a_period():
    counts = signal(8, 8, "sequential")
    frames, meta = stream(counts, "sequential")
    stall = 2 * 80_000 + 30_000  # clock frozen from rev 2, slot 135 until rev 5
    for i, m in enumerate(meta):
        if 2 <= m["index"] < 5 and (m["index"], m["first_slot"]) >= (2, 135):
            frames[i] = frame(
                m["first_slot"] == 0,
                m["seq"],
                m["rev"],
                m["first_slot"],
                slot_samples(counts[m["index"]], "sequential")[m["first_slot"] : m["first_slot"] + 45],
                stall,
            )
    dec, asm, revs = run(b"".join(frames))
    assert [r.rev for r in revs] == [0, 1, 5, 6, 7]
    assert asm.drop_reasons == {"bad_clock": 3}
    check_intact(revs, counts)


def test_false_header_claiming_a_long_frame_is_resolved():
    """A sync + plausible header in garbage claiming 255 x 255 samples holds decoding
    only until that many bytes arrived; the frames behind it then decode."""
    false = b"\xa5\x5a" + bytes([1, SIMULTANEOUS, 0, 0, 0, 0, 0, 0, 0, 0, 255, 255, 0, 0, 0, 0])
    counts = signal(80, 8, "simultaneous")
    data = false + b"".join(stream(counts, "simultaneous")[0])
    assert len(data) > 2 * 255 * 255 + 20
    dec, asm, revs = run(data, mode="simultaneous", chunk=7)
    assert dec.frame_errors == {"crc": 1} and dec.bytes_skipped == 1 + 17  # resynced right after the sync
    assert len(revs) == 80 and asm.revolutions_dropped == 0
    check_intact(revs, counts)
