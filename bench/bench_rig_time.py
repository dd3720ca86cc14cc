"""Rig time: the paper's fixed protocol against a designed frequency list with adaptive averaging.

How (honestly): this drives reduction DIRECTLY on simulated revolutions - no engine, no
transports, no drives. Revolutions come from the simulator's physics (sim.physics.RigPhysics
of the default scenario "paper", config/sim.toml: hydrostatic bearing, measurement chain and
every disturbance on) through sim.revolutions.simulate_revolutions (the A/D board's scan),
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
             at each ratio and the prior coefficients (what `design --noise-from RUN` does); then
             reduction.frequency_list.propose asks for every coefficient's predicted standard
             error at most the paper list's (scales = those errors, target 1) in the least rig
             time; its blocks average adaptively: AveragingRule.adaptive(target, n*/2, 3 n*)
             with the channel target that n* revolutions reach on the pilot's noise.

Achieved standard errors: the spread (and the RMS error against the simulator's true K, C,
D) of the identified coefficients over repeated runs with different noise seeds.

Run: python3 bench/bench_rig_time.py [runs]   (default 40 runs per protocol and model)
"""

from __future__ import annotations

import dataclasses
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
from sim.config import scenario  # noqa: E402
from sim.fits import constant_fit  # noqa: E402
from sim.physics import RigPhysics  # noqa: E402
from sim.revolutions import simulate_revolutions  # noqa: E402

SPIN = 1000 * RPM
PAPER = [round(0.2 + k / 9, 6) for k in range(10)]
MODELS = ("kcd11", "kc8")


def new_physics(seed: int) -> RigPhysics:
    """The simulator's default scenario (config/sim.toml: the paper's rig) with a noise seed."""
    return RigPhysics(dataclasses.replace(scenario("paper"), seed=seed))


def run_point(physics, rig, ratios, rule: AveragingRule):
    """One operating point: blocks at +-ratio x spin; (table, blocks, rig seconds)."""
    gains = np.asarray(rig.gains)
    rows, us, ns, orbits, blocks, t = [], [], [], [], [], 0.0
    for direction in (+1, -1):
        for r in (sorted(ratios, reverse=True) if direction > 0 else sorted(ratios)):
            orbit = direction * r * SPIN
            period = 2 * math.pi / abs(orbit)
            slots, values = simulate_revolutions(physics, SPIN, orbit, rule.max_revolutions, t0=t)
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
    """The simulator's truth: the constant K, C, D best fitting the true Z over the reference
    band (Table 1 ratios) at this spin, in the spec's column order (higher orders 0)."""
    w = np.asarray(physics.cfg.bearing.reference_ratios) * SPIN
    mats = constant_fit(w, physics.impedances(SPIN, w))
    return np.array([mats[t.matrix][t.entries[0]] if t.order == 0 else 0.0 for t in spec.terms])


def pilot(rig, spec):
    """Noise (4,) per revolution, prior theta and the channels' per-revolution relative noise."""
    physics = new_physics(10_000)
    table, blocks, _ = run_point(physics, rig, PAPER, AveragingRule.fixed(50))
    per_row = table.u * np.sqrt(table.n_records)[:, None]
    ratios = np.round(np.asarray(table.orbit) / SPIN, 6)
    noise_ratios = np.unique(ratios)
    u_rev = np.array([np.median(per_row[ratios == r], axis=0) for r in noise_ratios])
    worst = np.array([np.max(b.relative_uncertainty) * math.sqrt(b.n_records) for b in blocks])
    rel_rev = (noise_ratios, np.array([np.median(worst[ratios == r]) for r in noise_ratios]))
    theta = identify(table, spec.model, method="wls").theta
    radius = float(np.mean(np.sqrt((np.abs(table.x) ** 2 + np.abs(table.y) ** 2) / 2)))
    return (u_rev, noise_ratios, radius), theta, rel_rev


def design(rig, spec, noise, theta, rel_rev):
    u_rev, noise_ratios, radius = noise
    paper = predict(DesignProblem(spec, theta, SPIN, radius, u_rev, 50, noise_ratios=noise_ratios), PAPER)
    problem = DesignProblem(spec, theta, SPIN, radius, u_rev, 50, scales=paper.std_errors, noise_ratios=noise_ratios)
    grid = allowed_ratios(min(PAPER), max(PAPER))  # the paper's band: the truth is a fit over it
    prop = propose(problem, grid, target=1.0, block_overhead=rig.settle.hold_s + rig.estimates.store_s)
    n_star = revolutions_for(prop.best, 50, 1.0)
    # the worst channel's per-revolution relative noise at the designed ratios (pilot, interpolated)
    worst_channel = float(np.median(np.interp(prop.best.ratios, *rel_rev)))
    target = worst_channel / math.sqrt(n_star)
    return prop.best.ratios, n_star, AveragingRule.adaptive(target, max(10, n_star // 2), max(3 * n_star, 20)), paper


def achieved(rig, spec, ratios, rule, runs: int):
    est, times, used = [], [], []
    for seed in range(runs):
        physics = new_physics(seed + 1)
        table, blocks, t = run_point(physics, rig, ratios, rule)
        est.append(identify(table, spec.model, method="wls").theta)
        times.append(t)
        used += [b.n_records for b in blocks]
    true = truth(new_physics(1), spec)
    est = np.array(est)
    return est.std(axis=0, ddof=1), np.sqrt(np.mean((est - true) ** 2, axis=0)), float(np.mean(times)), used


def compare(rig, model: str, runs: int) -> None:
    """One model: pilot, design, then the paper's protocol, the designed list with adaptive
    averaging and the designed list with a fixed n* revolutions; one line per coefficient."""
    t0 = time.perf_counter()
    spec = model_spec(model)
    noise, theta, rel_rev = pilot(rig, spec)
    ratios, n_star, rule, paper_pred = design(rig, spec, noise, theta, rel_rev)
    sd_p, rms_p, t_p, _ = achieved(rig, spec, PAPER, AveragingRule.fixed(50), runs)
    sd_a, rms_a, t_a, used = achieved(rig, spec, ratios, rule, runs)
    sd_f, rms_f, t_f, _ = achieved(rig, spec, ratios, AveragingRule.fixed(n_star), runs)
    print(f"\n{model}: pilot orbit radius {noise[2] * 1e6:.3g} um; designed ratios "
          f"{', '.join(f'{r:g}' for r in ratios)} x both, n* = {n_star}; adaptive: target "
          f"{rule.target * 100:.3g} % per channel, revolutions {rule.min_revolutions}..{rule.max_revolutions} "
          f"(used {min(used)}..{max(used)}, mean {np.mean(used):.1f})")
    print(f"  rig time: paper {t_p:.1f} s; designed+adaptive {t_a:.1f} s (ratio {t_a / t_p:.3f}); "
          f"designed fixed n* {t_f:.1f} s (ratio {t_f / t_p:.3f})")
    print(f"  {'coef':6} {'paper SD':>10} {'predicted':>10} {'SD adapt':>9} {'SD fixed':>9} "
          f"{'paper RMS':>10} {'RMS adapt':>10} {'RMS fixed':>10}   (SD, RMS of designed: ratio to paper)")
    for k, name in enumerate(spec.names):
        print(f"  {name:6} {sd_p[k]:10.4g} {paper_pred.std_errors[k]:10.4g} {sd_a[k] / sd_p[k]:9.3f} "
              f"{sd_f[k] / sd_p[k]:9.3f} {rms_p[k]:10.4g} {rms_a[k] / rms_p[k]:10.3f} {rms_f[k] / rms_p[k]:10.3f}")
    print(f"  worst SD ratio: adaptive {np.max(sd_a / sd_p):.3f}, fixed {np.max(sd_f / sd_p):.3f}; worst RMS "
          f"ratio: adaptive {np.max(rms_a / rms_p):.3f}, fixed {np.max(rms_f / rms_p):.3f}; RIG TIME RATIO "
          f"adaptive {t_a / t_p:.3f}, fixed {t_f / t_p:.3f}  ({time.perf_counter() - t0:.1f} s wall)")


def main() -> None:
    runs = int(sys.argv[1]) if len(sys.argv) > 1 else 40
    rig = load_rig(ROOT / "config" / "rig.toml")
    print(f"bench_rig_time: {runs} simulated runs per protocol at 1000 rpm, the default simulator scenario "
          "(all disturbances); reduction driven directly on simulated revolutions (no engine)")
    for model in MODELS:
        compare(rig, model, runs)


if __name__ == "__main__":
    main()
