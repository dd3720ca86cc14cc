"""The averaged block (raw counts, calibration, uncertainty) and the averaging rules:
fixed count, adaptive to an uncertainty target between a minimum and a maximum."""

from __future__ import annotations

import numpy as np
import pytest
from support.daq_encoder import signal, stream
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from daq.averaging_rule import AveragingRule, StopReason
from daq.averager import StreamingAverager
from reduction.noise import phasor_uncertainty
from daq.frames import FrameDecoder
from daq.revolutions import RevolutionAssembler, RevolutionBatch, channel_slots
from reduction.fourier import phasor

GAINS = np.array([0.1, -0.1, 0.1, 0.1, 5e-9, 5e-9, -5e-9, 5e-9])
OFFSETS = np.array([1.0, 0.0, -2.5, 0.0, 1e-6, 0.0, 0.0, -3e-6])


def batch(counts: np.ndarray, mode: str = "sequential", rev0: int = 0, period: float = 0.08) -> RevolutionBatch:
    r = len(counts)
    return RevolutionBatch(
        rev0 + np.arange(r, dtype=np.int64),
        80_000 * np.arange(r, dtype=np.int64),
        np.full(r, period),
        counts,
        channel_slots(counts.shape[1], mode),
    )


def test_raw_counts_reproduce_the_mean_exactly():
    counts = signal(37, 8, "sequential", noise=300, seed=3)
    avg = StreamingAverager(AveragingRule.fixed(30), GAINS, OFFSETS)
    (b,) = avg.push_batch(batch(counts, rev0=100))
    assert b.raw_counts.dtype == np.int16 and b.raw_counts.shape == (30, 8, 45)
    np.testing.assert_array_equal(b.raw_counts, counts[:30])
    assert np.array_equal(b.mean, b.raw_counts.mean(axis=0) * b.gains[:, None] + b.offsets[:, None])
    np.testing.assert_array_equal(b.gains, GAINS)
    np.testing.assert_array_equal(b.offsets, OFFSETS)
    np.testing.assert_array_equal(b.revs, np.arange(100, 130))
    np.testing.assert_array_equal(b.t_us, 80_000 * np.arange(30))
    np.testing.assert_array_equal(b.periods, np.full(30, 0.08))
    np.testing.assert_array_equal(b.slots, channel_slots(8, "sequential"))
    assert b.n_records == b.n_revolutions == 30 and b.stop_reason is StopReason.COUNT
    assert b.orbit_speed == pytest.approx(2 * np.pi / 0.08)
    # the records are the least-squares fundamentals of each revolution; the block's phasor is their mean
    np.testing.assert_allclose(b.record_phasors, phasor(counts[:30], b.theta) * GAINS, rtol=1e-10)
    np.testing.assert_allclose(b.phasors, b.record_phasors.mean(axis=0), rtol=1e-10)
    dev = b.record_phasors - b.record_phasors.mean(axis=0)
    expected_u = np.sqrt(np.sum(np.abs(dev) ** 2, axis=0) / 29 / 30)
    np.testing.assert_allclose(b.uncertainty, expected_u, rtol=1e-10)
    np.testing.assert_allclose(b.relative_uncertainty, expected_u / np.abs(b.phasors), rtol=1e-10)


def test_simultaneous_layout_and_single_revolution():
    counts = signal(3, 4, "simultaneous", noise=10, seed=1)
    (b,) = StreamingAverager(1).push_batch(batch(counts[:1], "simultaneous"))
    assert b.raw_counts.shape == (1, 4, 360) and np.all(np.isinf(b.uncertainty))
    assert np.array_equal(b.mean, counts[0].astype(float))


def test_stop_reasons():
    quiet = signal(200, 8, "sequential", noise=5, seed=2)  # relative u ~ 1e-3 after a few revolutions
    b = StreamingAverager(AveragingRule.adaptive(0.01, 12, 100)).push_batch(batch(quiet))[0]
    assert (b.stop_reason, b.n_records) == (StopReason.TARGET, 12)  # met at once: stops at the minimum
    assert np.all(b.relative_uncertainty <= 0.01)

    noisy = signal(200, 8, "sequential", noise=3000, seed=2)
    b = StreamingAverager(AveragingRule.adaptive(0.001, 5, 40)).push_batch(batch(noisy))[0]
    assert (b.stop_reason, b.n_records) == (StopReason.MAX, 40)
    assert np.any(b.relative_uncertainty > 0.001)

    # in between: stops at the first revolution where every channel meets the target
    mid = signal(200, 8, "sequential", noise=400, seed=4)
    b = StreamingAverager(AveragingRule.adaptive(0.02, 5, 200)).push_batch(batch(mid))[0]
    assert b.stop_reason is StopReason.TARGET and 5 < b.n_records < 200
    assert np.all(b.relative_uncertainty <= 0.02)
    shorter = StreamingAverager(AveragingRule.fixed(b.n_records - 1)).push_batch(batch(mid))[0]
    assert np.any(shorter.relative_uncertainty > 0.02)

    # a dead channel (no fundamental) never meets a relative target
    dead = signal(60, 2, "sequential", phasors=[1000, 0], noise=1, seed=5)
    b = StreamingAverager(AveragingRule.adaptive(0.05, 3, 50)).push_batch(batch(dead))[0]
    assert b.stop_reason is StopReason.MAX and b.n_records == 50


def tone_block(n: int, spin_turns: float, tone: float, noise: float, seed: int) -> np.ndarray:
    """(n, 8, 45) counts: a 1000-count fundamental per channel, a spin tone of ``tone``
    counts at spin_turns x the orbit frequency (it rotates from revolution to revolution),
    white noise of ``noise`` counts rms per sample."""
    rng = np.random.default_rng(seed)
    slots = channel_slots(8, "sequential")
    theta = slots * (2 * np.pi / 360)  # (8, 45)
    k = np.arange(n)[:, None, None]
    x = 1000 * np.cos(theta) + tone * np.cos(spin_turns * (theta + 2 * np.pi * k) + 0.3)
    return np.round(x + noise * rng.standard_normal(x.shape)).astype(np.int16)


def test_spin_tones_do_not_keep_an_adaptive_block_going():
    """A 300-count spin tone at 1/0.7 x the orbit frequency: the plain scatter counts it as
    noise and never reaches 0.5 %; with spin_turns the check takes it out and stops at about
    the count the white noise alone needs (relative u of one revolution 2 x 60 / sqrt(45) /
    1000 = 1.8 %: about 13 revolutions for 0.5 %), and the stored uncertainty is the one checked."""
    counts = tone_block(400, 1 / 0.7, tone=300, noise=60, seed=7)
    plain = StreamingAverager(AveragingRule.adaptive(0.005, 5, 400)).push_batch(batch(counts))[0]
    assert plain.stop_reason == "max"
    aware = StreamingAverager(AveragingRule.adaptive(0.005, 5, 400, spin_turns=1 / 0.7)).push_batch(batch(counts))[0]
    assert aware.stop_reason == "target" and 8 <= aware.n_records <= 30
    assert np.all(aware.uncertainty <= 0.005 * np.abs(aware.phasors) * (1 + 1e-9))
    # fed one revolution at a time, the same block
    one = StreamingAverager(AveragingRule.adaptive(0.005, 5, 400, spin_turns=1 / 0.7))
    blocks = [b for i in range(60) for b in one.push_batch(batch(counts[i : i + 1], rev0=i))]
    assert blocks[0].n_records == aware.n_records


def test_rules_refuse_nonsense():
    for args in [
        (0, 5, None),
        (6, 5, None),
        (3, 5, None),
        (1, 5, 0.01),
        (5, 10, 0.0),
        (5, 10, float("inf")),
        (5, 10, float("nan")),
    ]:
        with pytest.raises(ValueError):
            AveragingRule(*args)
    assert AveragingRule() == AveragingRule.fixed(50)


@pytest.mark.parametrize("kind", ["gains", "offsets"])
def test_a_calibration_that_is_not_finite_is_refused_when_the_averager_is_made(kind):
    """A NaN gain made every phasor of its channel NaN, found only when a block finished."""
    cal = {"gains": GAINS.copy(), "offsets": OFFSETS.copy()}
    cal[kind][5] = np.nan
    with pytest.raises(ValueError, match=f"{kind} must be finite"):
        StreamingAverager(5, **cal)


def test_uncertainty_matches_the_scatter_of_repeated_blocks():
    """Monte Carlo: 1000 blocks of 20 noisy revolutions per channel (noise 30 to 240
    counts). The RMS of the stated uncertainty equals the RMS deviation of the block
    phasors from their grand mean within 8 % per channel (the empirical value's own
    relative spread is 1/(2 sqrt(1000)) = 1.6 %: 5 sigma) and within 3 % pooled over
    the 8 channels (0.6 %: 5 sigma)."""
    m, n = 1000, 20
    noise = 30 * (1 + np.arange(8))
    clean = signal(m * n, 8, "sequential", noise=0, seed=0).astype(float)
    rng = np.random.default_rng(11)
    counts = np.round(clean + noise[None, :, None] * rng.standard_normal(clean.shape)).astype(np.int16)
    blocks = StreamingAverager(n).push_batch(batch(counts))
    assert len(blocks) == m
    ph = np.array([b.phasors for b in blocks])
    u = np.array([b.uncertainty for b in blocks])
    empirical = np.sqrt(np.sum(np.abs(ph - ph.mean(axis=0)) ** 2, axis=0) / (m - 1))
    stated = np.sqrt(np.mean(u**2, axis=0))
    np.testing.assert_allclose(stated, empirical, rtol=0.08)
    assert np.sqrt(np.mean(stated**2 / empirical**2)) == pytest.approx(1.0, abs=0.03)
    # and both scale as the noise: E|err|^2 = 4 sigma^2 / (45 samples) / 20 revolutions
    np.testing.assert_allclose(stated, np.sqrt(4 * noise**2 / 45 / n), rtol=0.08)


def test_scatter_uncertainty_formula():
    rec = np.array([[1 + 1j], [3 + 1j], [2 - 2j]])
    dev = np.abs(rec - (2 + 0j)) ** 2  # 1, 2, 4 ... mean is 2+0j
    assert phasor_uncertainty(rec)[0] == pytest.approx(np.sqrt(dev.sum() / 2 / 3))
    assert np.isinf(phasor_uncertainty(rec[:1])[0])


RULES = st.one_of(
    st.integers(1, 12).map(AveragingRule.fixed),
    st.tuples(st.integers(2, 10), st.integers(0, 10), st.floats(1e-4, 0.5)).map(
        lambda t: AveragingRule.adaptive(t[2], t[0], t[0] + t[1])
    ),
    st.tuples(st.integers(2, 10), st.integers(0, 10), st.floats(1e-4, 0.5), st.floats(0.6, 5.0)).map(
        lambda t: AveragingRule.adaptive(t[2], t[0], t[0] + t[1], spin_turns=t[3])
    ),
)
DAMAGE = st.lists(st.tuples(st.sampled_from(["flip", "drop"]), st.integers(0, 10**6), st.integers(1, 255)), max_size=8)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    rule=RULES,
    damage=DAMAGE,
    noise=st.floats(0, 2000),
    seed=st.integers(0, 2**16),
    cuts=st.lists(st.integers(0, 10**6), max_size=10),
    layout=st.sampled_from([(8, 45), (4, 90), (2, 180)]),
)
def test_adaptive_blocks_stay_in_bounds_and_never_average_damage(rule, damage, noise, seed, cuts, layout):
    channels, frame_slots = layout
    counts = signal(40, channels, "sequential", noise=noise, seed=seed)
    frames, meta = stream(counts, "sequential", frame_slots=frame_slots)
    pieces = [bytearray(f) for f in frames]
    for kind, where, value in damage:
        i = where % len(pieces)
        if kind == "drop":
            pieces[i] = bytearray()
        elif pieces[i]:  # one damaged byte: the frame fails its CRC
            pieces[i][where % len(pieces[i])] ^= value
    damaged = {m["rev"] for m, f, p in zip(meta, frames, pieces) if f != p}
    data = b"".join(pieces)
    bounds = sorted({0, len(data), *[c % (len(data) + 1) for c in cuts]})
    dec, asm = FrameDecoder(), RevolutionAssembler(channels, "sequential")
    avg = StreamingAverager(rule)
    blocks = []
    for a, z in zip(bounds, bounds[1:]):
        blocks += avg.push_batch(asm.push_batch(dec.feed_batch(data[a:z])))
    blocks += avg.push_batch(asm.flush())
    seen = []
    for b in blocks:
        assert rule.min_revolutions <= b.n_records <= rule.max_revolutions
        if rule.target is None:
            assert b.stop_reason == "count" and b.n_records == rule.max_revolutions
        elif b.stop_reason == "max":
            assert b.n_records == rule.max_revolutions
        else:
            assert b.stop_reason == "target"
            assert np.all(b.uncertainty <= rule.target * np.abs(b.phasors) * (1 + 1e-9))
        for r, raw in zip(b.revs, b.raw_counts):
            assert int(r) not in damaged
            np.testing.assert_array_equal(raw, counts[r])
        seen += b.revs.tolist()
    assert len(seen) == len(set(seen)) and seen == sorted(seen)
