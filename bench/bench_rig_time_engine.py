"""Rig time measured through the engine: `bench_rig_time.py --engine --runs N [--json]`.

Each run is a one-point sweep --sim in process (orbitrig.cli.simulated_rig + RunEngine, as
`orbitrig sweep --sim` builds them) at a time speed-up, one noise seed per run, at 1000 rpm,
scenario `paper` (the paper's rig) and `compressible` (frequency-dependent Z). Protocols:

  paper    : ratios 0.2 .. 1.2 (10), both directions, 50 revolutions per block
  designed : what `orbitrig design --match` proposes against the paper matrix with the model
             test kept (reduction.adequacy_design.allocate_keeping_test): noise and prior
             from a pilot of the paper protocol (bench_rig_time.design's pilot, not counted)
  per-direction : the same with --per-direction (each whirl direction of each ratio a block of
             its own, the matrix's [orbit] whirl list; allocate_keeping_test(per_direction=True))
  sequential : [orbit] sequential = true: an initial list spread for the model test (SPREAD, one
             ratio in each of the five slices of the paper's span, 10 revolutions each), then
             blocks chosen by the engine among the drives' band until every kcd11 coefficient's
             predicted standard error is at most the paper list's at 50 revolutions (at the
             point's own noise and coefficients: [sequential] match_ratios), cap SEQUENTIAL_CAP_S

Both identify kcd11 and kcd11 power:1 (wls); the adequacy test is kcd11 none against kcd11
power:1, rejected at p < 0.01. Rig time of the point: the simulator's own clock (simulated
seconds) from the point's first progress event to its result; on a loaded machine the
engine's lag counts as rig time too (both protocols alike). Figures:

  time_ratio        protocol / paper, mean rig time of the point, scenario paper
  sd_ratio_worst    the worst kcd11 coefficient's spread ratio (protocol / paper), scenario paper
  sd_ratio_interval each coefficient's 90 % confidence interval of that ratio (F distribution,
                    reduction.spread); sd_goal: "met" when every interval lies at or below 1.1,
                    "missed" when one lies above it, else "undecided" at this many runs (the
                    worst of eleven ratios read off 20 runs is biased upward: bench/bench_spread.py)
  rmse_ratio_worst  the same for the RMS error against the simulator's constant-K, C, D truth
  adequacy_detect   per protocol, the fraction of compressible runs rejecting the constant model
  time_ratio_plan   the sweep plan's estimate of the same ratio (no engine lag; designed and
                    per-direction, with the list: ratios, revolutions, whirl)
  blocks_s          (sequential) mean rig seconds of the point's blocks at its stop, counted as the
                    plan counts them (no engine lag, no decision time), scenario paper
  matrix_time_ratio the paper matrix's planned rig time (manual settings included) in the
                    fastest order over the written order (orbitrig.run.point_order)

Per protocol (designed, per-direction, sequential; by default designed and sequential) under
"protocols"; goal per protocol: time_ratio <= 0.5, sd_ratio_worst <= 1.1, adequacy detection >=
the paper protocol's. `--scenarios paper` runs the paper scenario alone (the same seeds): every
figure but the compressible ones and the goal.
"""

from __future__ import annotations

import asyncio
import dataclasses
import json
import math
import tempfile
import time
from pathlib import Path

import numpy as np

from reduction.spread import spread_ratio_interval, spread_verdict
from rigunits import RPM

SPEEDUP = 20.0
RETRIES = 2  # a run that fails (e.g. the Modbus link lost on a loaded machine) is run again this often


class RunFailedError(RuntimeError):
    """One simulated run did not complete."""


ALPHA = 0.01
SD_GOAL = 1.1  # the goal on every coefficient's spread ratio
SCENARIOS = ("paper", "compressible")
MODELS = ("none", "power:1")
#: the paper's Table 1 operating point with a list of ratios and revolutions (both benches)
TABLE1_POINT = """name = "{name}"
[operating]
spin_rpm = [1000.0]
recess_pressure_mpa = [0.4826]
pressure_ratio = [0.25]
static_eccentricity = [0.0]
dynamic_eccentricity = [0.04]
[orbit]
ratios = [{ratios}]
revolutions = [{counts}]
"""
MATRIX = (
    TABLE1_POINT
    + """[[models]]
model = "kcd11"
method = "wls"
[[models]]
model = "kcd11"
freq_dep = "power:1"
method = "wls"
"""
)

SPREAD = [0.2, 0.4, 0.65, 0.8, 1.2]  # the sequential protocol's initial list: one ratio per slice of 0.2..1.2
SEQUENTIAL_CAP_S = 200.0  # rig seconds of a sequential point's blocks (the paper's take about 160 s)
SEQUENTIAL = """sequential = true
[sequential]
match_ratios = [{paper}]
match_revolutions = 50
cap_s = {cap}
"""
PROTOCOLS = ("designed", "sequential")  # the default; also per-direction
DESIGNED = ("designed", "per-direction")  # the protocols with a list from the pilot


def sequential_matrix(paper_list) -> str:
    """The sequential protocol's matrix text (the [orbit] table's last key, then the bounds)."""
    head, models = MATRIX.split("[[models]]", 1)
    return (
        head.format(name="bench", ratios=", ".join(map(str, SPREAD)), counts=", ".join(["10"] * len(SPREAD)))
        + SEQUENTIAL.format(paper=", ".join(map(str, paper_list)), cap=SEQUENTIAL_CAP_S)
        + "[[models]]"
        + models
    )


def designed_list(rig, pilot_design, per_direction: bool = False) -> tuple[list[float], list[int], list[str] | None]:
    """The paper matrix's --match proposal with the model test, from the pilot's noise and prior:
    (ratios, revolutions, with ``per_direction`` each block's whirl direction, else None)."""
    from reduction.adequacy_design import allocate_keeping_test, model_test
    from reduction.frequency_list import allowed_ratios
    from reduction.models import model_spec

    spec = model_spec("kcd11")
    problem, paper = pilot_design(rig, spec)
    test = model_test([("kcd11", "none"), ("kcd11", "power:1")], paper)
    d = rig.drives
    grid = allowed_ratios(d.min_ratio, min(d.max_ratio, d.max_orbit_rpm / 1000.0))
    prior = dict(zip(spec.names, map(float, problem.theta)))
    a = allocate_keeping_test(
        test,
        spec,
        prior,
        problem.spin,
        problem.radius,
        grid,
        problem.noise_at,
        (paper, 50),
        block_overhead=rig.block_overhead_s,
        per_direction=per_direction,
    )
    return list(a.ratios), list(a.revolutions), [w.value for w in a.whirl] if per_direction else None


async def _one_run(rig, matrix, scenario: str, seed: int, out: Path, speedup: float) -> float:
    """Run the one-point matrix on the simulator; the point's simulated seconds."""
    from orbitrig.cli.simulated_rig import simulated_rig
    from orbitrig.run.engine import RunEngine
    from orbitrig.run.events import ProgressEvent, ResultEvent
    from orbitrig.run.modbus_log import keep_pymodbus_off_the_terminal
    from orbitrig.run.scenario import Scenario
    from orbitrig.run.states import ConfirmMode
    from sim.scenario_files import scenario as sim_scenario

    keep_pymodbus_off_the_terminal()
    marks: dict[str, float] = {}
    cfg = dataclasses.replace(sim_scenario(scenario), seed=seed)
    async with simulated_rig(speedup, cfg, Scenario(scenario)) as (sim, access):
        engine = RunEngine(rig, out_dir=out, access=access, confirm_mode=ConfirmMode.AUTO, operator="bench")

        def sim_time() -> float:  # the simulator runs in its own process: ask its control link
            return float(sim.link.call("state")["sim_time"])

        def on_event(ev) -> None:
            if isinstance(ev, ProgressEvent) and "start" not in marks:
                marks["start"] = sim_time()
            elif isinstance(ev, ResultEvent):
                marks["end"] = sim_time()

        engine.subscribe(on_event)
        outcome = await engine.run(matrix)
    if str(outcome.status) != "completed" or "end" not in marks:
        raise RunFailedError(f"{scenario} seed {seed}: run {outcome.status}: {outcome.message}")
    return marks["end"] - marks["start"]


def _read(out: Path) -> tuple[np.ndarray, float, float]:
    """(kcd11 coefficients, adequacy p-value, a sequential point's rig seconds of blocks at its
    stop, counted the plan's way without engine lag; nan for a fixed list)."""
    import h5py

    from orbitrig import open_run
    from reduction.models import model_spec

    run = open_run(out)
    coeffs = run.fit(0, "piezo", "kcd11", "none", "wls").result["coefficients"]
    adequacy = run.fit(0, "piezo", "kcd11", "power:1", "wls").adequacy or {}
    with h5py.File(out / "run.h5") as f:
        g = f["points"]["0000"]
        blocks_s = float(g["sequential"].attrs["spent_s"]) if "sequential" in g else math.nan
    return (
        np.array([float(coeffs[n]) for n in model_spec("kcd11").names]),
        float(adequacy.get("p_value", 1.0)),
        blocks_s,
    )


def list_matrix(ratios, counts, whirl=None, name: str = "bench") -> str:
    """A fixed list's matrix text (``whirl``: each entry's directions, the [orbit] table's last key)."""
    head, models = MATRIX.split("[[models]]", 1)
    head = head.format(name=name, ratios=", ".join(map(str, ratios)), counts=", ".join(map(str, counts)))
    ways = "" if whirl is None else "whirl = [" + ", ".join(f'"{w}"' for w in whirl) + "]\n"
    return head + ways + "[[models]]" + models


def _seed_run(rig, scenario: str, matrix, seed: int, speedup: float, failed: list) -> tuple:
    """(rig seconds, kcd11 coefficients, adequacy p-value, blocks' seconds) of one seed, run again
    on a failure."""
    for attempt in range(RETRIES + 1):  # a loaded machine can lose the Modbus link: run the seed again
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "run"
            try:
                seconds = asyncio.run(_one_run(rig, matrix, scenario, seed, out, speedup))
            except RunFailedError as err:
                failed.append(str(err))
                if attempt == RETRIES:
                    raise
                continue
            return (seconds, *_read(out))
    raise AssertionError("unreachable")


def _runs(rig, texts: dict, runs: int, speedup: float, partial: Path | None, scenarios=SCENARIOS) -> dict:
    """Every protocol and scenario, seed by seed (interleaved: a cut-short bench still compares
    like with like); each run appended to ``partial`` (JSON lines) when given. A scenario's seeds
    are the same whichever others run."""
    from orbitrig.config import matrix_from_text

    matrices = {k: matrix_from_text(t, "bench.toml") for k, t in texts.items()}
    res = {sc: {k: {"est": [], "times": [], "p": [], "blocks_s": [], "failed": []} for k in texts} for sc in scenarios}
    for n in range(runs):
        for sc in scenarios:
            for j, k in enumerate(texts):
                r = res[sc][k]
                seconds, theta, pv, blocks_s = _seed_run(
                    rig, sc, matrices[k], 1000 * SCENARIOS.index(sc) + 500 * j + 1 + n, speedup, r["failed"]
                )
                r["blocks_s"].append(blocks_s)
                r["times"].append(seconds)
                r["est"].append(theta)
                r["p"].append(pv)
                if partial is not None:
                    with partial.open("a") as f:
                        f.write(
                            json.dumps(
                                {
                                    "scenario": sc,
                                    "protocol": k,
                                    "run": n,
                                    "seconds": seconds,
                                    "theta": theta.tolist(),
                                    "p": pv,
                                    "blocks_s": blocks_s,
                                }
                            )
                            + "\n"
                        )
    return {
        sc: {
            k: {**v, "est": np.array(v["est"]), "times": np.array(v["times"]), "p": np.array(v["p"])}
            for k, v in r.items()
        }
        for sc, r in res.items()
    }


def _truth(rig, scenario: str) -> np.ndarray:
    """The constant K, C, D best fitting the scenario's true Z over its reference band
    (bench_rig_time.truth's way), in kcd11's column order."""
    from reduction.models import model_spec
    from sim.scenario_files import scenario as sim_scenario
    from sim.fits import constant_fit
    from sim.physics import RigPhysics

    physics = RigPhysics(sim_scenario(scenario))
    physics.set_manual(
        orbit_radius=0.04 * rig.bearing.clearance,
        static_eccentricity=0.0,
        recess_pressure=0.4826e6,
        pressure_ratio=0.25,
    )
    spin = 1000 * RPM
    w = np.asarray(physics.cfg.bearing.reference_ratios) * spin
    mats = constant_fit(w, physics.impedances(spin, w))
    return np.array([mats[t.matrix][t.entries[0]] for t in model_spec("kcd11").terms])


def plan_time_ratio(rig, ratios, counts, paper_list, whirl=None) -> float:
    """The sweep's own estimate (orbitrig.run.plan, manual settings left out) of the designed
    point over the paper's: what the measured time_ratio would be on an idle machine."""
    from orbitrig.config import matrix_from_text
    from orbitrig.run.plan import make_plan, summarize

    def seconds(r, n, w=None) -> float:
        sm = summarize(make_plan(matrix_from_text(list_matrix(r, n, w, "plan"), "plan.toml"), rig).steps)
        return sm.duration - sm.by_kind.get("manual settings", 0.0)

    return seconds(ratios, counts, whirl) / seconds(paper_list, [50] * len(paper_list))


def _names() -> list[str]:
    from reduction.models import model_spec

    return model_spec("kcd11").names


def matrix_time_ratio(rig) -> float:
    from orbitrig.config import default_matrix_path, load_matrix
    from orbitrig.run.plan import make_plan, summarize

    plan = make_plan(load_matrix(default_matrix_path("paper")), rig)
    written = make_plan(plan.matrix, rig, range(len(plan.points)))
    return summarize(plan.steps).duration / summarize(written.steps).duration


def _ratios(p: dict, d: dict, truth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(spread ratio, RMS error ratio) per kcd11 coefficient, protocol ``d`` over paper ``p``."""
    sd = d["est"].std(axis=0, ddof=1) / p["est"].std(axis=0, ddof=1)
    rmse = np.sqrt(np.mean((d["est"] - truth) ** 2, axis=0)) / np.sqrt(np.mean((p["est"] - truth) ** 2, axis=0))
    return sd, rmse


def _protocol_figures(res: dict, k: str, truth: np.ndarray, detect: dict) -> dict:
    """One protocol's figures against the paper protocol's (scenario paper; compressible when run)."""
    p, d = res["paper"]["paper"], res["paper"][k]
    sd, rmse = _ratios(p, d, truth)
    n, m = len(d["est"]), len(p["est"])
    f = {
        "time_ratio": float(np.mean(d["times"]) / np.mean(p["times"])),
        "sd_ratio_worst": float(np.max(sd)),
        "rmse_ratio_worst": float(np.max(rmse)),
        "sd_ratio": dict(zip(_names(), np.round(sd, 3).tolist())),
        "sd_ratio_interval": dict(zip(_names(), np.round(spread_ratio_interval(sd, n, m), 3).tolist())),
        "sd_goal": str(spread_verdict(sd, n, m, SD_GOAL)),
        "rmse_ratio": dict(zip(_names(), np.round(rmse, 3).tolist())),
    }
    if "compressible" in res:
        c = res["compressible"]
        f["time_ratio_compressible"] = float(np.mean(c[k]["times"]) / np.mean(c["paper"]["times"]))
    detected = k in detect and detect[k] >= detect["paper"]  # not run: not shown
    f["goal_met"] = bool(f["time_ratio"] <= 0.5 and f["sd_ratio_worst"] <= SD_GOAL and detected)
    return f


def engine_figures(
    rig,
    runs: int,
    pilot_design,
    paper_list,
    speedup: float = SPEEDUP,
    protocols=PROTOCOLS,
    partial: Path | None = None,
    scenarios=SCENARIOS,
) -> dict:
    """Every figure of the module doc, per protocol, and whether its goal is met (scenarios: at
    least paper; without compressible, no adequacy figures and no goal met)."""
    t0 = time.perf_counter()
    lists = {k: designed_list(rig, pilot_design, k == "per-direction") for k in DESIGNED if k in protocols}
    texts = {
        "paper": list_matrix(paper_list, [50] * len(paper_list)),
        "sequential": sequential_matrix(paper_list),
        **{k: list_matrix(*v) for k, v in lists.items()},
    }
    res = _runs(rig, {k: texts[k] for k in ("paper", *protocols)}, runs, speedup, partial, scenarios)
    truth = _truth(rig, "paper")
    c = res.get("compressible", {})
    detect = {k: float(np.mean(v["p"] < ALPHA)) for k, v in c.items()}
    figures = {k: _protocol_figures(res, k, truth, detect) for k in protocols}
    for k, (ratios, counts, whirl) in lists.items():
        plan = plan_time_ratio(rig, ratios, counts, paper_list, whirl)
        figures[k].update(
            ratios=ratios, revolutions=counts, time_ratio_plan=plan, **({"whirl": whirl} if whirl else {})
        )
    if "sequential" in figures:
        figures["sequential"].update(
            initial_ratios=SPREAD,
            cap_s=SEQUENTIAL_CAP_S,
            blocks_s=float(np.mean(res["paper"]["sequential"]["blocks_s"])),
        )
    out = {
        "runs": runs,
        "speedup": speedup,
        "time_s": {sc: {k: float(np.mean(v["times"])) for k, v in r.items()} for sc, r in res.items()},
        "protocols": figures,
        "adequacy_detect": detect,
        "sd_ratio_mc_sigma": 1 / math.sqrt(max(runs - 1, 1)),
        "matrix_time_ratio": matrix_time_ratio(rig),
        "failed_runs_retried": [m for r in res.values() for v in r.values() for m in v["failed"]],
        "wall_s": round(time.perf_counter() - t0, 1),
    }
    out["goal_met"] = any(f["goal_met"] for f in figures.values())
    return out
