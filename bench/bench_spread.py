"""Predicted against achieved spread of the identified coefficients, and what the engine bench's
worst spread ratio reads at its run count.

How (honestly): like bench/bench_rig_time.py this drives reduction DIRECTLY on simulated
revolutions (sim.revolutions at 1000 rpm, scenario "paper": every disturbance on; quantised
and averaged by daq's StreamingAverager) - no engine, drives or transports - but it keeps the
sweep's own block records (orbitrig.run.identification.block_record), orbit table (piezo, the
rig's corrections) and identification (kcd11, wls). Protocols, as the engine bench runs them
(bench/bench_rig_time_engine.py):

  paper      : ratios 0.2 .. 1.2 (10), both directions, 50 revolutions per block
  designed   : the paper matrix's `design --match` proposal with the model test kept, from a
               pilot of the paper protocol (not counted)
  sequential : the engine bench's sequential matrix: the initial spread list at 10 revolutions,
               then each block the sweep's own decision (orbitrig.run.sequential_point.choose)
               on the blocks measured so far, until the target or the cap

Per protocol and kcd11 coefficient: the spread over `--runs` runs (its own seeds) against the
paper protocol's, and against the standard error the fit predicts from its information matrix
(mean over the runs): a ratio near 1 says the per-revolution noise model the designs use is
honest on the simulator's disturbances. The blocks' rig seconds are counted as the sweep plan
counts them (orbitrig.run.sequential_point.spent_seconds). Then the engine bench's figure: the
worst of the eleven spread ratios from `--short` runs per protocol (the engine bench's count),
redrawn `--draws` times from these runs (without replacement): its median and 5-95 % range,
and how often it reads at most 1.1.

Run: python3 -m bench.bench_spread [--runs 200] [--short 20] [--json]
Exit 1 when a coefficient's spread over its predicted standard error is off 1 by more than
TOLERANCE plus three Monte Carlo sigmas (the prediction the designs rely on is then not honest).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time

import numpy as np

from bench.bench_rig_time import PAPER, ROOT, SPIN, blocks_in_order, pilot_problem, simulated_block
from bench.bench_rig_time_engine import SD_GOAL as GOAL
from bench.bench_rig_time_engine import designed_list, sequential_matrix
from daq.averaging_rule import AveragingRule
from orbitrig.config import LMS, load_rig, matrix_from_text
from orbitrig.run.corrections import Corrections
from orbitrig.run.identification import block_record, orbit_table
from orbitrig.run.sequential_point import PointSoFar, choose, spent_seconds
from orbitrig.run.sequential_rule import SequentialRule, sequential_rule
from orbitrig.run.steps import Block
from reduction.identify import identify
from reduction.models import model_spec
from reduction.rig_time import block_time
from reduction.spread import spread_ratio_interval
from reduction.whirl import Directions
from sim.scenario_files import scenario
from sim.physics import RigPhysics

MODEL = "kcd11"
SEED_STRIDE = 100_000  # each protocol's runs take their own seeds
#: target: every coefficient's spread within this fraction of its predicted standard error, beyond
#: the Monte Carlo scatter of a standard deviation (3 / sqrt(2 (runs - 1)))
TOLERANCE = 0.15


class Point:
    """One simulated operating point: its block records in the order they ran."""

    def __init__(self, rig, seed: int):
        self.rig = rig
        self.physics = RigPhysics(dataclasses.replace(scenario("paper"), seed=seed))
        self.recs: list = []
        self.t = 0.0

    def measure(self, direction: int, ratio: float, revolutions: int) -> None:
        orbit = direction * ratio * SPIN
        blk = simulated_block(self.physics, self.rig, orbit, AveragingRule.fixed(revolutions), self.t)
        self.t += block_time(orbit, blk.n_records) + self.rig.block_overhead_s
        self.recs.append(block_record(Block(len(self.recs), direction, orbit), blk, self.rig))

    def identified(self) -> tuple[np.ndarray, np.ndarray]:
        """(kcd11 coefficients, their standard errors from the fit's covariance)."""
        table = orbit_table(SPIN, self.recs, self.rig.channel_index, LMS[0], Corrections.of_rig(self.rig))
        fit = identify(table, MODEL, method="wls")
        return fit.theta, np.sqrt(np.diag(fit.covariance))


def fixed_point(point: Point, ratios, counts) -> None:
    of = dict(zip(ratios, counts))
    for direction, r in blocks_in_order(ratios):
        point.measure(direction, r, of[r])


def sequential_point(point: Point, rule: SequentialRule, initial, counts) -> None:
    """The matrix's initial list, then the sweep's own choice block by block until it stops."""
    fixed_point(point, initial, counts)
    while True:
        c = choose(PointSoFar(rule, SPIN, tuple(point.recs), point.rig.channel_index))
        if c.ratio is None:
            return
        for w in Directions(c.direction).whirls:
            point.measure(w.sign, c.ratio, c.revolutions)


def protocols(rig) -> tuple[dict, SequentialRule]:
    """name -> function(point) running that protocol on a fresh point; the sequential rule."""
    ratios, counts = designed_list(rig, pilot_problem)
    matrix = matrix_from_text(sequential_matrix(PAPER), "bench.toml")
    rule = sequential_rule(matrix, rig, SPIN)
    if rule is None:
        raise SystemExit("the engine bench's sequential matrix is not sequential")
    initial = matrix.orbit.ratio_list
    start = [matrix.orbit.revolutions_at(k) for k in range(len(initial))]
    return {
        "paper": lambda p: fixed_point(p, PAPER, [50] * len(PAPER)),
        "designed": lambda p: fixed_point(p, ratios, counts),
        "sequential": lambda p: sequential_point(p, rule, initial, start),
    }, rule


def measure(rig, runs: int) -> dict:
    """Per protocol: (runs, p) coefficients and standard errors, (runs,) blocks' rig seconds."""
    run_of, rule = protocols(rig)
    out = {}
    for j, (name, run) in enumerate(run_of.items()):
        est, se, secs = [], [], []
        for n in range(runs):
            point = Point(rig, 1 + n + SEED_STRIDE * j)
            run(point)
            theta, std = point.identified()
            est.append(theta)
            se.append(std)
            secs.append(spent_seconds(rule, point.recs))
        out[name] = {"est": np.array(est), "se": np.array(se), "seconds": np.array(secs)}
    return out


def short_worst(paper: np.ndarray, other: np.ndarray, short: int, draws: int, rng) -> np.ndarray:
    """(draws,) the worst spread ratio from ``short`` runs of each, redrawn from the runs."""
    worst = np.empty(draws)
    for d in range(draws):
        a = other[rng.choice(len(other), short, replace=False)].std(axis=0, ddof=1)
        b = paper[rng.choice(len(paper), short, replace=False)].std(axis=0, ddof=1)
        worst[d] = np.max(a / b)
    return worst


def figures(res: dict, short: int, draws: int) -> dict:
    names = model_spec(MODEL).names
    p = res["paper"]
    rng = np.random.default_rng(25)
    out = {}
    for name, r in res.items():
        runs = len(r["est"])
        sd = r["est"].std(axis=0, ddof=1)
        f = {
            "time_ratio": float(np.mean(r["seconds"]) / np.mean(p["seconds"])),
            "sd_over_predicted": dict(zip(names, np.round(sd / r["se"].mean(axis=0), 3).tolist())),
        }
        if name != "paper":
            ratio = sd / p["est"].std(axis=0, ddof=1)
            bounds = spread_ratio_interval(ratio, runs, len(p["est"]))
            worst = short_worst(p["est"], r["est"], short, draws, rng) if min(runs, len(p["est"])) > short else None
            f.update(
                sd_ratio=dict(zip(names, np.round(ratio, 3).tolist())),
                sd_ratio_interval=dict(zip(names, np.round(bounds, 3).tolist())),
                sd_ratio_worst=float(np.max(ratio)),
            )
            if worst is not None:
                f[f"sd_ratio_worst_at_{short}_runs"] = {
                    "median": round(float(np.median(worst)), 3),
                    "p5_p95": np.round(np.percentile(worst, [5, 95]), 3).tolist(),
                    "fraction_at_most_goal": round(float(np.mean(worst <= GOAL)), 3),
                }
        out[name] = f
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=200, help="runs per protocol (default 200)")
    ap.add_argument("--short", type=int, default=20, help="the engine bench's runs per protocol (default 20)")
    ap.add_argument("--draws", type=int, default=2000, help="redraws of the short bench (default 2000)")
    ap.add_argument("--json", action="store_true", help="one JSON object")
    args = ap.parse_args()
    t0 = time.perf_counter()
    rig = load_rig(ROOT / "config" / "rig.toml")
    out = {
        "runs": args.runs,
        "sd_ratio_mc_sigma": round(1 / np.sqrt(args.runs - 1), 3),
        "protocols": figures(measure(rig, args.runs), args.short, args.draws),
    }
    out["wall_s"] = round(time.perf_counter() - t0, 1)
    out["prediction_tolerance"] = round(TOLERANCE + 3 / np.sqrt(2 * (args.runs - 1)), 3)
    off = {
        f"{name} {c}": v
        for name, f in out["protocols"].items()
        for c, v in f["sd_over_predicted"].items()
        if abs(v - 1) > out["prediction_tolerance"]
    }
    out["prediction_met"] = not off
    print(json.dumps(out) if args.json else "\n".join(report(out, args.short)))
    return 0 if not off else 1


def report(out: dict, short: int) -> list[str]:
    """The figures as lines: per protocol, per coefficient."""
    lines = [
        f"bench_spread: {out['runs']} runs per protocol at 1000 rpm, scenario paper, reduction on simulated "
        f"revolutions (Monte Carlo sigma of one SD ratio {out['sd_ratio_mc_sigma']}); {out['wall_s']} s wall",
        f"target: every SD / predicted within 1 +- {out['prediction_tolerance']}: "
        + ("met" if out["prediction_met"] else "NOT met"),
    ]
    for name, f in out["protocols"].items():
        lines.append(f"{name}: rig time of the blocks {f['time_ratio']:.3f} of the paper's")
        ratio, bounds = f.get("sd_ratio", {}), f.get("sd_ratio_interval", {})
        for c, v in f["sd_over_predicted"].items():
            vs = f"; SD / paper's {ratio[c]:.3f} (90 % {bounds[c][0]:.2f} .. {bounds[c][1]:.2f})" if c in ratio else ""
            lines.append(f"  {c:4} SD / predicted {v:.3f}{vs}")
        w = f.get(f"sd_ratio_worst_at_{short}_runs")
        if w:
            lines.append(
                f"  worst SD ratio {f['sd_ratio_worst']:.3f}; read off {short} runs each: median "
                f"{w['median']:.2f}, 5-95 % {w['p5_p95'][0]:.2f} .. {w['p5_p95'][1]:.2f}, "
                f"at most {GOAL} in {w['fraction_at_most_goal']:.0%}"
            )
    return lines


if __name__ == "__main__":
    sys.exit(main())
