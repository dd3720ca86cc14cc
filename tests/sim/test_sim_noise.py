"""Disturbances: 50-revolution synchronous averages land in the expected band."""

from __future__ import annotations

import math

import numpy as np

from sim.config import NoiseConfig, SimConfig
from sim.rig import SimRig
from support.sim_reader import channel_samples, fundamental, parse, read_tcp, revolutions

GAINS = np.array([0.1] * 4 + [5e-9] * 4)
SPIN = 150.0
M = 50  # revolutions averaged
N = 45  # samples per channel per revolution


async def record(cfg: SimConfig, orbit: float):
    async with SimRig(cfg, speedup=10.0, can_channel=None) as rig:
        rig.local_control(spin=SPIN, orbit=orbit)
        data = await read_tcp(rig.adc_server.port, min_revs=M + 1)
        true = rig.true_phasors(SPIN, orbit)
    revs = revolutions(parse(data)[0])[:M]
    assert len(revs) == M
    per_rev = np.array(
        [
            [fundamental(channel_samples(c, k)[1] * GAINS[k], channel_samples(c, k)[0]) for k in range(8)]
            for _, _, c in revs
        ]
    )  # (M, 8)
    return per_rev, np.array(list(true.values()))


async def test_white_noise_and_jitter_average_within_the_statistical_band():
    cfg = SimConfig()
    cfg.noise = NoiseConfig(
        runout=(),
        spin_force=(),
        bearing_orders=(),
        resonance_force=0.0,
        line_force=0.0,
        line_probe=0.0,
        speed_ripple=0.0,
    )
    per_rev, true = await record(cfg, 2 * math.pi * 13.7)
    nz = cfg.noise
    white = np.array([nz.piezo_white] * 2 + [nz.strain_white] * 2 + [nz.probe_white] * 4)
    # per-sample error: white noise, slot-edge jitter (amplitude x angle error), quantisation
    sigma = np.sqrt(white**2 + np.abs(true) ** 2 * nz.encoder_jitter**2 / 2 + GAINS**2 / 12)
    sigma_rev = sigma * math.sqrt(2 / N)  # std of Re and Im of one revolution's phasor
    scatter = np.std(per_rev.real, axis=0, ddof=1)
    np.testing.assert_allclose(scatter, sigma_rev, rtol=0.45)  # 4.5 sd of a 50-sample std
    err = np.abs(per_rev.mean(axis=0) - true)
    assert np.all(err < 5 * sigma_rev / math.sqrt(M)), err / (sigma_rev / math.sqrt(M))


async def test_all_disturbances_are_removed_by_time_averaging():
    """Run-out, spindle and ball-bearing orders, the housing resonance, line
    interference, ripple, white noise (the paper's rig): none synchronous with
    the orbit, so the 50-revolution average converges on the true phasors at
    the 1/sqrt(M) rate of the per-revolution scatter."""
    per_rev, true = await record(SimConfig(), -2 * math.pi * 13.7)
    single = np.abs(per_rev - true).max(axis=0)
    avg = np.abs(per_rev.mean(axis=0) - true)
    scatter = np.sqrt(np.mean(np.abs(per_rev - per_rev.mean(axis=0)) ** 2, axis=0))
    assert np.all(avg < 4 * scatter / math.sqrt(M)), avg / (scatter / math.sqrt(M))
    assert np.all(avg < 0.25 * single)  # the disturbances were there, averaging removed them
    # single revolutions are well off: forces by ~20 % (coherence ~0.95), probes by the run-out
    assert np.all(single[:4] > 0.1 * np.abs(true[:4]))
    assert np.all(single[4:] > 5e-3 * np.abs(true[4:]))
    assert np.all(avg[:4] < 0.1 * np.abs(true[:4])) and np.all(avg[4:] < 5e-3 * np.abs(true[4:]))  # 3.5 sd
