"""Coverage of the calibrated coefficients' U over simulator seeds.

Per seed: the clean scenario with its measurement chain on (each channel's gain error, the probes'
common sensitivity error, the anti-alias filters, the force channels' 20 µs delay) and drawn load
measuring system errors (piezo and strain gain within +-3 %, the strain gauges' lag within +-0.4
degree); `orbitrig calibrate loads, runout, delay, probes --sim` into a copy of the lab, then
`orbitrig sweep --sim` at the paper's Table 1 point (tests.support.e2e_sweep). Every kcd11
(constant, ols) coefficient of both systems is held against the simulator's truth in its U as the
sweep stores it (coefficients.csv KEY_U: each coefficient's k, Student's t at 95.45 % at its effective
dof, reduction.combined_dof; 95.45 % is reduction.statistics.U_COVERAGE): printed per matrix and
system, max |error| / U and the share within U; exit 1 when a coefficient stands more than 2 U off
or the share within U falls more than 3 binomial standard deviations of the entries below 95.45 %
(91.2 % for 220 entries, 86.0 % for 44; the entries of one seed share its calibration, so the bound
of independent entries is the stricter one).

    python3 -m bench.bench_calibration_coverage [--seeds 10] [--first 2] [--repeat 2]

A seed fixes the simulated rig, its errors and its noise, not which revolutions a block averages
(that follows the wall clock, docs/simulator.md "What a seed fixes"): `--repeat N` runs each seed N
times, prints how far the runs' error / U of each coefficient lie apart (max and rms over the
seed's entries) and counts every run's entries in the coverage.

About 60 to 90 s a seed and run on 2 loaded cores; each run's lab is removed after it.
"""

from __future__ import annotations

import argparse
import csv
import math
import shutil
import tempfile
from pathlib import Path

import numpy as np

from reduction.statistics import U_COVERAGE
from tests.support.cli_helpers import orbitrig
from tests.support.e2e_sweep import MATRIX, TABLE1_RATIOS
from tests.support.paths import ROOT
from tests.support.rig_configs import patient_rig_config

STEPS = ("loads", "runout", "delay", "probes")
KEYS = ("Kxx", "Kxy", "Kyx", "Kyy", "Cxx", "Cxy", "Cyx", "Cyy", "Dxx", "Dxy", "Dyy")


def _scenario(seed: int) -> tuple[str, str]:
    """(scenario TOML, what was drawn) of ``seed``."""
    rng = np.random.default_rng(1000 + seed)
    g_s, g_p = rng.uniform(-0.03, 0.03, 2)
    lag = math.radians(rng.uniform(-0.4, 0.4))
    clean = (ROOT / "config/sim/clean.toml").read_text(encoding="utf-8")
    chain_on = clean.replace("[chain]\nenabled = false", "[chain]\nenabled = true")
    text = f"seed = {seed}\n{chain_on}\n[lms]\npiezo_gain_error = {g_p}\nstrain_gain_error = {g_s}\nstrain_phase_lag = {lag}\n"
    return text, f"strain {g_s:+.4f}, piezo {g_p:+.4f}, strain lag {math.degrees(lag):+.3f} deg"


def _column(row: dict, name: str) -> float:
    return float(next(v for k, v in row.items() if k.split(" ")[0] == name))


def one_seed(lab: Path, seed: int) -> list[tuple[str, str, float]]:
    """[(system, coefficient, (identified - true) / U)] of one seed's calibrated sweep."""
    patient_rig_config(lab)
    shutil.copytree(ROOT / "config/calibration", lab / "calibration")
    text, _ = _scenario(seed)
    (lab / "scenario.toml").write_text(text, encoding="utf-8")
    common = ["--sim", "--sim-config", str(lab / "scenario.toml"), "--config", str(lab / "rig.toml")]
    common += ["--speedup", "40", "--operator", "bench"]
    for step in STEPS:
        p = orbitrig("calibrate", step, *common, timeout=300)
        if p.returncode:
            raise SystemExit(f"calibrate {step}, seed {seed}: {p.stderr[-2000:]}")
    (lab / "table1.toml").write_text(MATRIX.format(ratios=TABLE1_RATIOS), encoding="utf-8")
    p = orbitrig("sweep", *common, "--matrix", str(lab / "table1.toml"), "--out", str(lab / "run"), timeout=400)
    if p.returncode:
        raise SystemExit(f"sweep, seed {seed}: {p.stderr[-2000:]}")
    out = []
    with open(lab / "run" / "coefficients.csv", newline="", encoding="utf-8") as fh:
        for row in csv.DictReader(fh):
            if row.get("model") != "kcd11" or row.get("freq_dep", "none") not in ("none", ""):
                continue
            for key in KEYS:
                value, true, u = _column(row, key), _column(row, f"true_{key}"), _column(row, f"{key}_U")
                out.append((row["lms"], key, (value - true) / u))
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10, help="seeds run (default 10)")
    ap.add_argument("--first", type=int, default=2, help="the first seed (default 2)")
    ap.add_argument("--repeat", type=int, default=1, help="runs of each seed (default 1)")
    args = ap.parse_args()
    z: list[tuple[str, str, float]] = []
    for seed in range(args.first, args.first + args.seeds):
        runs = []
        for _ in range(max(1, args.repeat)):
            with tempfile.TemporaryDirectory(prefix="orbitrig-calcov-") as tmp:
                runs.append(one_seed(Path(tmp) / "lab", seed))
        z += [entry for run in runs for entry in run]
        print(f"seed {seed}: {_scenario(seed)[1]}{run_spread(runs)}", flush=True)
    worst = 0.0
    for lms in sorted({s for s, _, _ in z}):
        for m in "KCD":
            r = np.array([abs(v) for s, k, v in z if s == lms and k[0] == m])
            worst = max(worst, float(r.max()))
            print(f"{lms} {m}: {r.size} entries, max |error| / U {r.max():.2f}, within U {np.mean(r <= 1):.0%}")
    share = float(np.mean([abs(v) <= 1 for *_, v in z]))
    floor = share_floor(len(z))
    print(
        f"all: {len(z)} entries, max |error| / U {worst:.2f}, within U {share:.1%} "
        f"(target {U_COVERAGE:.2%}, at least {floor:.1%}: 3 binomial standard deviations of {len(z)})"
    )
    return 1 if worst > 2 or share < floor else 0


def run_spread(runs: list[list[tuple[str, str, float]]]) -> str:
    """How far the runs of one seed lie apart: max and rms over its entries of the difference of
    their error / U ('' for one run)."""
    if len(runs) < 2:
        return ""
    v = np.array([[e for *_, e in run] for run in runs])  # (runs, entries), the same order in each
    d = v - v[0]
    d = d[1:]
    return f"; runs apart by max {np.abs(d).max():.2f} U, rms {np.sqrt(np.mean(d * d)):.2f} U"


def share_floor(n: int) -> float:
    """The least share within U that n entries of a U covering U_COVERAGE give but for 3 binomial
    standard deviations (independent entries)."""
    return U_COVERAGE - 3 * math.sqrt(U_COVERAGE * (1 - U_COVERAGE) / n)


if __name__ == "__main__":
    raise SystemExit(main())
