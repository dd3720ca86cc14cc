"""Rig time: the paper's fixed protocol against a designed frequency list with adaptive averaging.

How (honestly): this drives reduction DIRECTLY on simulated revolutions - no engine, no
transports, no drives. Revolutions come from the simulator's physics (sim.physics.RigPhysics,
the default scenario, every disturbance on: white noise, runout, spindle-bearing orders,
line frequency, encoder jitter, speed ripple), sampled like the A/D board's sequential scan,
quantised with the rig's gains and averaged by daq's StreamingAverager (the sweep's averager)
under daq.averager.AveragingRule; each block's per-revolution phasors give the table's u_*,
and reduction.identify (weighted least squares) identifies the model.

Rig time (simulated seconds, one operating point at 1000 rpm): per block the revolutions
used plus one (finding the trigger) times the orbit period, the settle hold and the store
estimate of config/rig.toml, plus the orbit ramps (2 x the highest |Omega| at the ramp
rate) - the `orbitrig design` model; manual settings and the spin ramp are common to both.

Protocols:
  paper    : ratios 0.2 .. 1.2 (10), both directions, AveragingRule.fixed(50)
  designed : a pilot run of the paper's protocol (not counted) gives the per-revolution noise
             and the prior coefficients (what `design --noise-from RUN` does); then
             reduction.frequency_list.propose asks for every coefficient's predicted standard
             error at most the paper list's (scales = those errors, target 1) in the least rig
             time; its blocks average adaptively: AveragingRule.adaptive(target, 10, 3 n*)
             with the channel target that n* revolutions reach on the pilot's noise.

Achieved standard errors: the spread (and the RMS error against the simulator's true K, C,
D) of the identified coefficients over repeated runs with different noise seeds.

Run: python3 bench/bench_rig_time.py [runs]   (default 40 runs per protocol and model)
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from daq.averager import AveragingRule, StreamingAverager  # noqa: E402
from daq.revolutions import RevolutionBatch  # noqa: E402
from orbitrig.config import RPM, load_rig  # noqa: E402
from reduction.frequency_list import (DesignProblem, allowed_ratios, predict, propose,  # noqa: E402
                                      revolutions_for)
from reduction.identify import identify  # noqa: E402
from reduction.models import model_spec  # noqa: E402
from reduction.noise import phasor_uncertainty  # noqa: E402
from reduction.table import OrbitTable  # noqa: E402
from sim.config import SimConfig  # noqa: E402
from sim.physics import RigPhysics  # noqa: E402

SPIN = 1000 * RPM
PAPER = [round(0.2 + k / 9, 6) for k in range(10)]
MODELS = ("kcd11", "kc8")
SLOT = 2 * math.pi / 360


def revolutions(physics: RigPhysics, orbit: float, n: int, t0: float):
    """(slots (C, S), values (n, C, S)): n revolutions of the sequential scan at steady speed."""
    try:  # the simulator's own helper, where it has one
        from sim.revolutions import simulate_revolutions
    except ImportError:
        simulate_revolutions = None
    if simulate_revolutions is not None:
        return simulate_revolutions(physics, SPIN, orbit, n, t0=t0)
    C = len(physics.channels)
    slots = np.arange(360).reshape(-1, C).T
    g = np.arange(n * 360)
    t_nom = t0 + g * SLOT / abs(orbit)
    t = (t0 + np.cumsum(np.r_[0.0, np.diff(t_nom) / physics.ripple(t_nom[:-1])])).reshape(n, 360)
    values = np.empty((n, C, slots.shape[1]))
    inst = np.full(n * slots.shape[1], float(orbit))
    for k in range(C):
        tk = t[:, slots[k]].ravel()
        values[:, k, :] = physics.channel_values(k, np.tile(slots[k] * SLOT, n), tk, SPIN * tk,
                                                 inst, SPIN, orbit).reshape(n, -1)
    return slots, values


def run_point(physics, rig, ratios, rule: AveragingRule):
    """One operating point: blocks at +-ratio x spin; (table, blocks, rig seconds)."""
    gains = np.asarray(rig.gains)
    rows, us, ns, orbits, blocks, t = [], [], [], [], [], 0.0
    for direction in (+1, -1):
        for r in (sorted(ratios, reverse=True) if direction > 0 else sorted(ratios)):
            orbit = direction * r * SPIN
            period = 2 * math.pi / abs(orbit)
            slots, values = revolutions(physics, orbit, rule.max_revolutions, t)
            counts = np.clip(np.round(values / gains[:, None]), -32768, 32767).astype(np.int16)
            n = counts.shape[0]
            revs = np.arange(n, dtype=np.int64)
            batch = RevolutionBatch(revs, (revs * period * 1e6).astype(np.int64), np.full(n, period), counts, slots)
            _, block = StreamingAverager(rule, gains, np.zeros(gains.size)).take(batch)
            t += (block.n_records + 1) * period + rig.settle.hold_s + rig.estimates.store_s
            q = block.record_phasors
            recs = np.stack([(q[:, 4] + q[:, 6]) / 2, (q[:, 5] + q[:, 7]) / 2, q[:, 0], q[:, 1]], axis=1)
            rows.append(recs.mean(axis=0))
            us.append(phasor_uncertainty(recs, axis=0))
            ns.append(block.n_records)
            orbits.append(abs(orbit))
            blocks.append(block)
    t += 2 * max(ratios) * SPIN / rig.ramp_rate
    rows = np.array(rows)
    table = OrbitTable(SPIN, np.array(orbits), rows[:, 0], rows[:, 1], rows[:, 2], rows[:, 3],
                       n_records=np.array(ns), u=np.array(us))
    return table, blocks, t


def truth(physics, spec) -> np.ndarray:
    K, C, D = physics.coefficients(SPIN, SPIN)
    mats = {"K": K, "C": C, "D": D}
    return np.array([mats[t.matrix][t.entries[0]] if t.order == 0 else 0.0 for t in spec.terms])


def pilot(rig, spec):
    """Noise (4,) per revolution, prior theta and the channels' per-revolution relative noise."""
    physics = RigPhysics(SimConfig(seed=10_000))
    table, blocks, _ = run_point(physics, rig, PAPER, AveragingRule.fixed(50))
    u_rev = np.median(table.u * np.sqrt(table.n_records)[:, None], axis=0)
    rel_rev = np.array([b.relative_uncertainty * math.sqrt(b.n_records) for b in blocks])  # (blocks, C)
    theta = identify(table, spec.model, method="wls").theta
    return u_rev, theta, rel_rev


def design(rig, spec, u_rev, theta, rel_rev):
    radius = rig.bearing.clearance * 0.1
    paper = predict(DesignProblem(spec, theta, SPIN, radius, u_rev, 50), PAPER)
    problem = DesignProblem(spec, theta, SPIN, radius, u_rev, 50, scales=paper.std_errors)
    grid = allowed_ratios(rig.drives.min_ratio or 0.05, min(rig.drives.max_ratio, rig.drives.max_orbit_rpm / 1000))
    prop = propose(problem, grid, target=1.0, block_overhead=rig.settle.hold_s + rig.estimates.store_s)
    n_star = revolutions_for(prop.best, 50, 1.0)
    worst_channel = float(np.median(np.max(rel_rev, axis=1)))  # per-revolution relative noise
    target = worst_channel / math.sqrt(n_star)
    return prop.best.ratios, n_star, AveragingRule.adaptive(target, 10, max(3 * n_star, 20)), paper


def achieved(rig, spec, ratios, rule, runs: int):
    est, times, used = [], [], []
    for seed in range(runs):
        physics = RigPhysics(SimConfig(seed=seed + 1))
        table, blocks, t = run_point(physics, rig, ratios, rule)
        est.append(identify(table, spec.model, method="wls").theta)
        times.append(t)
        used += [b.n_records for b in blocks]
    true = truth(RigPhysics(SimConfig(seed=1)), spec)
    est = np.array(est)
    return est.std(axis=0, ddof=1), np.sqrt(np.mean((est - true) ** 2, axis=0)), float(np.mean(times)), used


def main() -> None:
    runs = int(sys.argv[1]) if len(sys.argv) > 1 else 40
    rig = load_rig(ROOT / "config" / "rig.toml")
    print(f"bench_rig_time: {runs} simulated runs per protocol, 1000 rpm, orbit radius 6 um, "
          "default simulator scenario with all disturbances; reduction driven directly (no engine)")
    for model in MODELS:
        t0 = time.perf_counter()
        spec = model_spec(model)
        u_rev, theta, rel_rev = pilot(rig, spec)
        ratios, n_star, rule, paper_pred = design(rig, spec, u_rev, theta, rel_rev)
        sd_p, rms_p, t_p, _ = achieved(rig, spec, PAPER, AveragingRule.fixed(50), runs)
        sd_d, rms_d, t_d, used = achieved(rig, spec, ratios, rule, runs)
        print(f"\n{model}: designed ratios {', '.join(f'{r:g}' for r in ratios)} x both; "
              f"n* = {n_star}; adaptive target {rule.target * 100:.3g} % per channel, "
              f"revolutions {rule.min_revolutions}..{rule.max_revolutions} (used {min(used)}..{max(used)}, "
              f"mean {np.mean(used):.1f})")
        print(f"  rig time: paper {t_p:.1f} s, designed {t_d:.1f} s, ratio {t_d / t_p:.3f}")
        print(f"  {'coef':6} {'paper SD':>11} {'designed SD':>11} {'SD ratio':>8} {'paper RMS':>11} "
              f"{'designed RMS':>12} {'RMS ratio':>9} {'predicted':>10}")
        for k, name in enumerate(spec.names):
            print(f"  {name:6} {sd_p[k]:11.4g} {sd_d[k]:11.4g} {sd_d[k] / sd_p[k]:8.3f} {rms_p[k]:11.4g} "
                  f"{rms_d[k]:12.4g} {rms_d[k] / rms_p[k]:9.3f} {paper_pred.std_errors[k]:10.4g}")
        print(f"  worst SD ratio {np.max(sd_d / sd_p):.3f}, worst RMS ratio {np.max(rms_d / rms_p):.3f}, "
              f"rig time ratio {t_d / t_p:.3f}  ({time.perf_counter() - t0:.1f} s wall)")


if __name__ == "__main__":
    main()
