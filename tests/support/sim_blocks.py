"""Averaged blocks of synthetic revolutions with known noise, for the design's Monte Carlo checks.

A block: every revolution of each channel is Re(q_bar e^{i theta}) at the channel's slots
(sequential scan of 8 channels, 45 slots each) plus white Gaussian noise of a stated rms per
sample, quantised with the rig's gains and averaged by daq's StreamingAverager (the
sweep's averager) under an AveragingRule. The per-revolution phasor noise of a channel with
sample rms sigma over S slots is u = 2 sigma / sqrt(S) (E|err|^2 = 4 sigma^2 / S).

Channel order as config/rig.toml: fx_piezo, fy_piezo, fx_strain, fy_strain, x_a, y_a, x_b, y_b.
"""

from __future__ import annotations

import numpy as np

from daq.averaging_rule import AveragingRule
from daq.averager import AveragedBlock, StreamingAverager
from daq.revolutions import RevolutionBatch, channel_slots
from reduction.design import design_orbits
from reduction.impedance import forces, impedance
from reduction.noise import phasor_uncertainty
from reduction.table import OrbitTable

GAINS = np.array([0.1, 0.1, 0.1, 0.1, 5e-9, 5e-9, 5e-9, 5e-9])
SLOTS = channel_slots(8, "sequential")
S = SLOTS.shape[1]


def phasor_noise(sample_rms) -> np.ndarray:
    """Per-revolution phasor noise u (same unit) of channels with this per-sample rms."""
    return 2.0 * np.asarray(sample_rms, dtype=float) / np.sqrt(S)


def table_noise(force_rms: float, probe_rms: float) -> np.ndarray:
    """(4,) per-revolution noise of the table's x, y (mean of two planes), fx, fy (piezo)."""
    up, uf = phasor_noise(probe_rms), phasor_noise(force_rms)
    return np.array([up / np.sqrt(2), up / np.sqrt(2), uf, uf])


def channel_phasors(x: complex, y: complex, fx: complex, fy: complex) -> np.ndarray:
    """(8,) true phasors of the channels: both load systems read f, both planes read x, y."""
    return np.array([fx, fy, fx, fy, x, y, x, y], dtype=complex)


def averaged_block(
    truth: np.ndarray,
    sample_rms: np.ndarray,
    rule: AveragingRule,
    rng,
    period: float = 0.1,
    damaged: tuple[int, ...] = (),
    averager: StreamingAverager | None = None,
) -> AveragedBlock:
    """Average revolutions of the true channel phasors ``truth`` (8,) with white noise of
    ``sample_rms`` (8,) per sample; revolutions listed in ``damaged`` carry a wild value
    (1e4 counts) in channel 0 and must never be averaged (they are left out of the batch,
    as the assembler drops them). ``averager``: one between blocks (as the sweep keeps one
    over a point's blocks: its phasor weights are computed once), else a new one."""
    n = rule.max_revolutions + len(damaged)
    theta = SLOTS * 2 * np.pi / 360
    clean = np.real(truth[:, None] * np.exp(1j * theta))
    values = clean[None] + rng.normal(size=(n,) + SLOTS.shape) * np.asarray(sample_rms)[:, None]
    counts = np.clip(np.round(values / GAINS[:, None]), -32768, 32767).astype(np.int16)
    keep = np.array([k not in damaged for k in range(n)])
    counts[~keep, 0, :] = 10_000
    revs = np.arange(n, dtype=np.int64)[keep]
    batch = RevolutionBatch(
        revs, (revs * period * 1e6).astype(np.int64), np.full(revs.size, period), counts[keep], SLOTS
    )
    averager = StreamingAverager(rule, GAINS, np.zeros(8)) if averager is None else averager
    assert averager.rule == rule and averager.count == 0, "the averager must be between blocks"
    used, block = averager.take(batch)
    assert block is not None, f"{used} revolutions did not complete a block"
    return block


def block_row(block: AveragedBlock) -> tuple[np.ndarray, np.ndarray]:
    """(x, y, fx, fy) complex and their u (4,) from one block (piezo forces, mean of planes)."""
    r = block.record_phasors
    recs = np.stack([(r[:, 4] + r[:, 6]) / 2, (r[:, 5] + r[:, 7]) / 2, r[:, 0], r[:, 1]], axis=1)
    return recs.mean(axis=0), phasor_uncertainty(recs, axis=0)


def simulated_table(
    spec, theta, spin: float, ratios, radius: float, force_rms: float, probe_rms: float, rule: AveragingRule, rng
) -> tuple[OrbitTable, list[AveragedBlock]]:
    """One simulated run at one operating point: circular orbits of ``radius`` at ``ratios``
    x spin in both directions, forces f = -Z(theta) d, blocks averaged under ``rule``."""
    orbit, x, y = design_orbits(np.asarray(ratios) * spin / (2 * np.pi), "both", radius)
    fx, fy = forces(impedance(spec, theta, orbit), x, y)
    rms = np.array([force_rms] * 4 + [probe_rms] * 4)
    rows, us, blocks = [], [], []
    averager = StreamingAverager(rule, GAINS, np.zeros(8))  # one over the run's blocks, as the sweep's
    for k in range(orbit.size):
        truth = channel_phasors(x[k], y[k], fx[k], fy[k])
        block = averaged_block(truth, rms, rule, rng, period=2 * np.pi / orbit[k], averager=averager)
        row, u = block_row(block)
        rows.append(row)
        us.append(u)
        blocks.append(block)
    rows = np.array(rows)
    table = OrbitTable(
        spin,
        orbit,
        rows[:, 0],
        rows[:, 1],
        rows[:, 2],
        rows[:, 3],
        n_records=np.array([b.n_records for b in blocks]),
        u=np.array(us),
    )
    return table, blocks
