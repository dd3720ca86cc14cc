"""Rig time: the paper's fixed protocol against a designed list with revolutions per ratio.

How (honestly): this drives reduction DIRECTLY on simulated revolutions - no engine, no
transports, no drives. Revolutions come from the simulator's physics (sim.physics.RigPhysics
of the default scenario "paper", config/sim.toml: hydrostatic bearing, measurement chain and
every disturbance on) through sim.revolutions.simulate_revolutions (the A/D board's scan),
quantised with the rig's gains and averaged by daq's StreamingAverager (the sweep's averager)
under daq.averaging_rule.AveragingRule; each block's u_* is the sweep's (reduction.noise.
mean_uncertainty: the per-revolution scatter without the spin tones' rotating leakage), and
reduction.identify (weighted least squares) identifies the model.

Rig time (simulated seconds, one operating point at 1000 rpm), as `orbitrig design` counts
it: per block the revolutions used plus one (finding the trigger) times the orbit period, the
settle hold and the store estimate of config/rig.toml, plus the orbit ramps (2 x the highest
|Omega| at the ramp rate); manual settings and the spin ramp are common to both protocols.

Protocols:
  paper    : ratios 0.2 .. 1.2 (10), both directions, AveragingRule.fixed(50)
  designed : a pilot run of the paper's protocol (not counted) gives the per-revolution noise
             at each ratio (smoothed, reduction.frequency_list.smooth_noise) and the prior
             coefficients - what `orbitrig design --noise-from RUN --match` does; then
             reduction.allocation.allocate asks for every coefficient's predicted standard
             error at most the paper list's, in the least rig time, over the drives' band
             (rig.toml: ratios 0.1 .. 1.5, none within 0.1 of 1), with revolutions per ratio.
             Run with those fixed counts, and adaptively: each ratio's target
             (reduction.allocation.adaptive_targets) between MIN_REVOLUTIONS and
             MAX_FACTOR x its count.

Achieved standard errors: the spread (and the RMS error against the simulator's true K, C,
D) of the identified coefficients over repeated runs with different noise seeds; each SD
ratio carries a Monte Carlo uncertainty of about 1/sqrt(runs - 1) (two SDs of `runs` runs).

Run: python3 -m bench.bench_rig_time [runs]   (default 200 runs per protocol and model)
Through the engine (sweep --sim in process; figures as JSON per protocol, designed,
per-direction and sequential; exit 1 when no protocol meets the goal):
     python3 -m bench.bench_rig_time --engine --runs N --json   (bench/bench_rig_time_engine.py)
"""

from __future__ import annotations

import dataclasses
import math
import sys
import time
from pathlib import Path

import numpy as np

from bench.bench_rig_time_engine import TABLE1_POINT
from daq.averaging_rule import AveragingRule
from daq.averager import StreamingAverager
from daq.revolutions import RevolutionBatch
from orbitrig.config import MIN_RATIOS, RPM, load_rig, matrix_from_text
from orbitrig.run.plan import make_plan, summarize
from reduction.misfit import list_shift
from reduction.allocation import adaptive_targets, allocate
from reduction.frequency_list import DesignProblem, allowed_ratios, predict, smooth_noise
from reduction.identify import identify
from reduction.models import model_spec
from reduction.noise import mean_uncertainty
from reduction.rig_time import block_time
from reduction.table import OrbitTable
from sim.scenario_files import scenario
from sim.fits import constant_fit
from sim.physics import RigPhysics
from sim.revolutions import simulate_revolutions

ROOT = Path(__file__).resolve().parents[1]
SPIN = 1000 * RPM
PAPER = [round(0.2 + k / 9, 6) for k in range(10)]
MODELS = ("kcd11", "kc8")
MIN_REVOLUTIONS = 50  # adaptive blocks: never fewer
MAX_FACTOR = 3  # adaptive blocks: at most this many times the ratio's allocated count


def new_physics(seed: int) -> RigPhysics:
    """The simulator's default scenario (config/sim.toml: the paper's rig) with a noise seed."""
    return RigPhysics(dataclasses.replace(scenario("paper"), seed=seed))


def simulated_block(physics, rig, orbit: float, rule, t0: float):
    """One block at ``orbit`` (rad/s, signed) and SPIN from t0 (simulated s): the A/D board's
    revolutions quantised with the rig's gains and averaged by daq's StreamingAverager under
    ``rule``; the AveragedBlock."""
    gains = np.asarray(rig.gains)
    period = 2 * math.pi / abs(orbit)
    slots, values = simulate_revolutions(physics, SPIN, orbit, rule.max_revolutions, t0=t0)
    counts = np.clip(np.round(values / gains[:, None]), -32768, 32767).astype(np.int16)
    n = counts.shape[0]
    revs = np.arange(n, dtype=np.int64)
    batch = RevolutionBatch(revs, (revs * period * 1e6).astype(np.int64), np.full(n, period), counts, slots)
    return StreamingAverager(rule, gains, np.zeros(gains.size)).take(batch)[1]


def blocks_in_order(ratios) -> list[tuple[int, float]]:
    """(direction, ratio) of a list's blocks in the order they run: forward from the highest
    ratio down, then backward from the lowest up (the shortest orbit ramps)."""
    return [(+1, r) for r in sorted(ratios, reverse=True)] + [(-1, r) for r in sorted(ratios)]


def run_point(physics, rig, ratios, rules):
    """One operating point: blocks at +-ratio x spin, ``rules`` one AveragingRule per ratio;
    (table, revolutions used per block, rig seconds)."""
    rule_of = dict(zip(ratios, rules))
    rows, us, ns, orbits, t = [], [], [], [], 0.0
    for direction, r in blocks_in_order(ratios):
        orbit = direction * r * SPIN
        block = simulated_block(physics, rig, orbit, rule_of[r], t)
        t += block_time(orbit, block.n_records) + rig.block_overhead_s
        q = block.record_phasors
        recs = np.stack([(q[:, 4] + q[:, 6]) / 2, (q[:, 5] + q[:, 7]) / 2, q[:, 0], q[:, 1]], axis=1)
        rows.append(recs.mean(axis=0))
        us.append(mean_uncertainty(recs, 1 / r))
        ns.append(block.n_records)
        orbits.append(abs(orbit))
    t += 2 * max(ratios) * SPIN / rig.ramp_rate
    rows = np.array(rows)
    table = OrbitTable(
        SPIN, np.array(orbits), rows[:, 0], rows[:, 1], rows[:, 2], rows[:, 3], n_records=np.array(ns), u=np.array(us)
    )
    return table, ns, t


def truth(physics, spec) -> np.ndarray:
    """The simulator's truth: the constant K, C, D best fitting the true Z over the reference
    band (Table 1 ratios) at this spin, in the spec's column order (higher orders 0)."""
    w = np.asarray(physics.cfg.bearing.reference_ratios) * SPIN
    mats = constant_fit(w, physics.impedances(SPIN, w))
    return np.array([mats[t.matrix][t.entries[0]] if t.order == 0 else 0.0 for t in spec.terms])


def pilot_problem(rig, spec) -> tuple[DesignProblem, list[float]]:
    """Pilot (the paper's protocol, seed 10000): the design problem with its smoothed noise per
    ratio, prior coefficients and orbit radius; and the paper's list."""
    table, _, _ = run_point(new_physics(10_000), rig, PAPER, [AveragingRule.fixed(50)] * len(PAPER))
    per_rev = table.u * np.sqrt(table.n_records)[:, None]
    ratios = np.round(np.asarray(table.orbit) / SPIN, 6)
    at = np.unique(ratios)
    u_rev = smooth_noise(at, np.array([np.median(per_rev[ratios == r], axis=0) for r in at]))
    theta = identify(table, spec.model, method="wls").theta
    radius = float(np.mean(np.sqrt((np.abs(table.x) ** 2 + np.abs(table.y) ** 2) / 2)))
    return DesignProblem(spec, theta, SPIN, radius, u_rev, 50, noise_ratios=at), PAPER


def design(rig, spec):
    """Pilot, then the allocation that matches the paper list's predicted standard errors;
    (ratios, counts, targets, paper prediction, allocation)."""
    problem, _ = pilot_problem(rig, spec)
    theta, radius = problem.theta, problem.radius
    paper = predict(problem, PAPER)
    d = rig.drives
    grid = allowed_ratios(d.min_ratio, min(d.max_ratio, d.max_orbit_rpm / 1000.0))
    alloc = allocate(
        spec,
        theta,
        SPIN,
        radius,
        grid,
        problem.noise_at(grid),
        paper.std_errors,
        block_overhead=rig.block_overhead_s,
    )
    targets = adaptive_targets(
        spec, theta, SPIN, radius, alloc.ratios, alloc.revolutions, problem.noise_at(alloc.ratios)
    )
    return list(alloc.ratios), list(alloc.revolutions), targets, paper, alloc


MATRIX = (
    TABLE1_POINT
    + """[[models]]
model = "{model}"
"""
)


def plan_seconds(rig, model: str, ratios, counts) -> tuple[float, float]:
    """The sweep's own estimate (orbitrig.run.plan) of a one-point matrix at these ratios and
    fixed counts: (whole point incl. manual settings, identification and the final stop;
    the same without the manual settings), physical seconds."""
    text = MATRIX.format(
        name="bench", ratios=", ".join(map(str, ratios)), counts=", ".join(map(str, counts)), model=model
    )
    plan = summarize(make_plan(matrix_from_text(text), rig).steps)
    return plan.duration, plan.duration - plan.by_kind.get("manual settings", 0.0)


def plan_line(rig, model: str, ratios, counts, adaptive_extra_s: float) -> tuple[str, str]:
    """The sweep's plan of the point for the paper's list and the designed one (fixed counts, and
    adaptive: `adaptive_extra_s` more acquisition), and the summary's two plan ratios. A designed
    list of one ratio has no plan: a matrix needs MIN_RATIOS orbit frequencies (orbitrig.config.matrix)."""
    whole_p, acq_p = plan_seconds(rig, model, PAPER, [50] * len(PAPER))
    if len(ratios) < MIN_RATIOS:
        return (
            f"  the sweep's plan of the point: paper {acq_p:.1f} s; designed: none, the sweep refuses a matrix of "
            f"{len(ratios)} ratio (at least {MIN_RATIOS} orbit frequencies)",
            "none",
        )
    whole_d, acq_d = plan_seconds(rig, model, ratios, counts)
    acq_a = acq_d + adaptive_extra_s  # the adaptive blocks' revolutions instead of the fixed counts
    line = (
        f"  the sweep's plan of the point (spin and orbit ramps, verification, identification; no manual "
        f"settings): paper {acq_p:.1f} s, designed fixed {acq_d:.1f} s (ratio {acq_d / acq_p:.3f}), designed "
        f"adaptive {acq_a:.1f} s (ratio {acq_a / acq_p:.3f}); with the 120 s of manual settings {whole_p:.0f} s "
        f"vs {whole_d:.0f} s (ratio {whole_d / whole_p:.3f})"
    )
    return line, f"{acq_d / acq_p:.3f}, {acq_a / acq_p:.3f}"


def misfit_line(rig, spec, ratios, counts) -> str:
    """kc7/kc8 leave D out: the shift of their estimates from the paper's list to the
    designed one that the pilot's kcd12 fit predicts (reduction.misfit, what `orbitrig
    design --noise-from` warns about), against the shift the simulator's true Z gives."""
    if "d" in spec.model:
        return ""
    rich = model_spec("kcd12")
    table, _, _ = run_point(new_physics(10_000), rig, PAPER, [AveragingRule.fixed(50)] * len(PAPER))
    fit = identify(table, "kcd12", method="wls")
    u = np.median(table.u * np.sqrt(table.n_records)[:, None], axis=0)
    radius = float(np.mean(np.sqrt((np.abs(table.x) ** 2 + np.abs(table.y) ** 2) / 2)))
    lists = ((PAPER, 50, u), (ratios, counts, u))
    pilot = list_shift(spec, rich, fit.theta, fit.covariance, SPIN, radius, *lists)
    true = list_shift(spec, rich, truth(new_physics(1), rich), np.zeros((12, 12)), SPIN, radius, *lists)
    j = int(np.argmax(np.abs(true.shift)))
    return (
        f"  misfit: {spec.model} has no D; moving to the designed list shifts {spec.names[j]} by "
        f"{true.shift[j]:.3g} on the true Z (pilot's kcd12 fit predicts {pilot.shift[j]:.3g} +- "
        f"{2 * pilot.std[j]:.3g}, 2 sigma)"
    )


def achieved(rig, spec, ratios, rules, runs: int):
    est, times, used = [], [], []
    for seed in range(runs):
        table, ns, t = run_point(new_physics(seed + 1), rig, ratios, rules)
        est.append(identify(table, spec.model, method="wls").theta)
        times.append(t)
        used.append(ns)
    true = truth(new_physics(1), spec)
    est = np.array(est)
    return est.std(axis=0, ddof=1), np.sqrt(np.mean((est - true) ** 2, axis=0)), float(np.mean(times)), np.array(used)


def compare(rig, model: str, runs: int) -> None:
    """One model: pilot, allocation, then the paper's protocol and the designed list with
    fixed and with adaptive counts; one line per coefficient."""
    t0 = time.perf_counter()
    spec = model_spec(model)
    ratios, counts, targets, paper_pred, alloc = design(rig, spec)
    fixed = [AveragingRule.fixed(n) for n in counts]
    adaptive = [
        AveragingRule.adaptive(float(t), min(MIN_REVOLUTIONS, n), MAX_FACTOR * n, spin_turns=1 / r)
        for t, n, r in zip(targets, counts, ratios)
    ]
    sd_p, rms_p, t_p, _ = achieved(rig, spec, PAPER, [AveragingRule.fixed(50)] * len(PAPER), runs)
    sd_f, rms_f, t_f, _ = achieved(rig, spec, ratios, fixed, runs)
    sd_a, rms_a, t_a, used = achieved(rig, spec, ratios, adaptive, runs)
    print(
        f"\n{model}: designed ratios {', '.join(f'{r:g}' for r in ratios)} x both, revolutions "
        f"{', '.join(map(str, counts))} (predicted rig time {alloc.rig_time_s:.1f} s + ramps); adaptive targets "
        f"{', '.join(f'{t * 100:.3g}' for t in targets)} % (used per block: mean "
        f"{', '.join(f'{m:.0f}' for m in used.mean(axis=0))}, range {used.min()}..{used.max()})"
    )
    print(
        f"  rig time: paper {t_p:.1f} s; designed fixed {t_f:.1f} s (ratio {t_f / t_p:.3f}); "
        f"designed adaptive {t_a:.1f} s (ratio {t_a / t_p:.3f})"
    )
    print(
        f"  {'coef':6} {'paper SD':>10} {'predicted':>10} {'SD fixed':>9} {'predicted':>9} {'SD adapt':>9} "
        f"{'paper RMS':>10} {'RMS fixed':>10} {'RMS adapt':>10}   (designed: ratio to paper)"
    )
    for k, name in enumerate(spec.names):
        print(
            f"  {name:6} {sd_p[k]:10.4g} {paper_pred.std_errors[k]:10.4g} {sd_f[k] / sd_p[k]:9.3f} "
            f"{alloc.std_errors[k] / paper_pred.std_errors[k]:9.3f} {sd_a[k] / sd_p[k]:9.3f} "
            f"{rms_p[k]:10.4g} {rms_f[k] / rms_p[k]:10.3f} {rms_a[k] / rms_p[k]:10.3f}"
        )
    line, plan_ratios = plan_line(rig, model, ratios, counts, t_a - t_f)
    print(line)
    line = misfit_line(rig, spec, ratios, counts)
    if line:
        print(line)
    mc = 1 / math.sqrt(runs - 1)
    print(
        f"  worst SD ratio: fixed {np.max(sd_f / sd_p):.3f}, adaptive {np.max(sd_a / sd_p):.3f} (Monte Carlo "
        f"1 sigma of one ratio ~{mc:.3f}); worst RMS ratio: fixed {np.max(rms_f / rms_p):.3f}, adaptive "
        f"{np.max(rms_a / rms_p):.3f}; RIG TIME RATIO fixed {t_f / t_p:.3f}, adaptive {t_a / t_p:.3f} (sweep plan "
        f"{plan_ratios})  "
        f"({time.perf_counter() - t0:.1f} s wall)"
    )


def main() -> int:
    import argparse
    import json

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("runs_pos", nargs="?", type=int, help="runs per protocol (reduction-only mode)")
    ap.add_argument("--runs", type=int, help="runs per protocol and scenario")
    ap.add_argument(
        "--engine",
        action="store_true",
        help="through the engine: sweep --sim in process (bench/bench_rig_time_engine.py)",
    )
    ap.add_argument("--json", action="store_true", help="print one JSON object (--engine)")
    ap.add_argument("--speedup", type=float, default=20.0, help="simulated / wall time (--engine)")
    ap.add_argument(
        "--protocols",
        default="designed,sequential",
        help="protocols against the paper's (--engine): designed, per-direction, sequential",
    )
    ap.add_argument("--partial", type=Path, help="append each run's figures to this file as it ends (--engine)")
    ap.add_argument(
        "--scenarios",
        default="paper,compressible",
        help="simulator scenarios (--engine): paper (spread and time) and compressible (adequacy)",
    )
    args = ap.parse_args()
    rig = load_rig(ROOT / "config" / "rig.toml")
    if args.engine:
        from bench.bench_rig_time_engine import SCENARIOS, engine_figures

        scenarios = tuple(args.scenarios.split(","))
        if "paper" not in scenarios or not set(scenarios) <= set(SCENARIOS):
            ap.error(f"--scenarios: paper and any of {', '.join(SCENARIOS[1:])}")
        protocols = tuple(args.protocols.split(","))
        figures = engine_figures(
            rig, args.runs or 20, pilot_problem, PAPER, args.speedup, protocols, args.partial, scenarios
        )
        print(json.dumps(figures, indent=None if args.json else 1))
        return 0 if figures["goal_met"] else 1
    runs = args.runs or args.runs_pos or 200
    print(
        f"bench_rig_time: {runs} simulated runs per protocol at 1000 rpm, the default simulator scenario "
        "(all disturbances); reduction driven directly on simulated revolutions (no engine)"
    )
    for model in MODELS:
        compare(rig, model, runs)
    return 0


if __name__ == "__main__":
    sys.exit(main())
