"""`orbitrig design`'s result as one JSON-ready object (its printed form and the saved design
file: orbitrig.cli.design_output).

Rig time of a list at one operating point (s, physical): per block the averaged revolutions
plus one (finding the trigger) times the orbit period, the settle hold and the store estimate
of rig.toml; plus the orbit drive's ramps (forward from the highest |Omega| down, backward
back up: 2 x the highest |Omega| at the rig's ramp rate). Manual settings and the spin ramp
are the same for every list and left out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from orbitrig.cli.design_inputs import DesignInputError
from orbitrig.config import MIN_RATIOS, MIN_REVOLUTIONS, RPM
from orbitrig.load_systems import LoadSystem
from reduction.rig_time import Ways
from reduction.whirl import Directions
from rigunits import coefficient_unit, in_hz, micrometres


def rig_time(rig, ratios, spin: float, revolutions, directions: Ways) -> float:
    """Physical seconds the blocks of ``ratios`` take at spin (rad/s), ``revolutions`` one
    count or one per ratio, ``directions`` one for all or one per ratio
    (reduction.rig_time.point_time; see the module doc)."""
    from reduction.rig_time import point_time

    return point_time(ratios, spin, revolutions, directions, per_block_s=rig.block_overhead_s, ramp_rate=rig.ramp_rate)


def _list_object(rig, problem, pred, revolutions: int, directions: Directions, whirl=None) -> dict:
    """A list's prediction ``pred`` as the output gives it; ``whirl``: each ratio's directions
    (in the order of ``pred.ratios``), None: ``directions`` for all."""
    names = problem.spec.names
    ok = pred.std_errors is not None
    ways = [directions] * len(pred.ratios) if whirl is None else list(whirl)
    return {
        "ratios": list(pred.ratios),
        "orbit_hz": [in_hz(r * problem.spin) for r in pred.ratios],  # as the run plans them (Block.orbit_hz)
        "directions": directions,
        "whirl": [Directions(w).value for w in ways],
        "revolutions": revolutions,
        "identifiable": ok,
        "std_errors": {n: float(v) for n, v in zip(names, pred.std_errors)} if ok else None,
        "relative_pct": {n: float(v) * 100 for n, v in zip(names, pred.relative)} if ok else None,
        "worst_relative_pct": float(pred.worst) * 100 if ok else None,
        "rig_time_s": rig_time(rig, pred.ratios, problem.spin, revolutions, ways),
    }


def _noise_object(noise) -> dict:
    """{"u_revolution": {x, y, fx, fy}, "source"}; measured noise: one value per ratio ("ratios")."""
    u = np.asarray(noise.u_revolution, dtype=float)
    cols = ("x", "y", "fx", "fy")
    if noise.ratios is None:
        return {"u_revolution": dict(zip(cols, map(float, u))), "source": noise.source}
    return {
        "u_revolution": {c: [float(v) for v in u[:, k]] for k, c in enumerate(cols)},
        "ratios": [float(r) for r in noise.ratios],
        "source": noise.source,
    }


def _band(rig, spin_rpm: float, keep_away: float):
    from reduction.frequency_list import GRID_STEP, allowed_ratios

    d = rig.drives
    if spin_rpm > d.max_spin_rpm:
        raise DesignInputError(f"--spin {spin_rpm:g} rpm is above the rig's drives.max_spin_rpm = {d.max_spin_rpm:g}")
    lo = d.min_ratio if d.min_ratio else GRID_STEP
    hi = min(d.max_ratio if d.max_ratio is not None else 1.5, d.max_orbit_rpm / spin_rpm)
    return allowed_ratios(lo, hi, keep_away=keep_away), lo, hi


def _candidate_warnings(ratios, lo: float, hi: float, keep_away: float) -> list[str]:
    from reduction.frequency_list import near_one

    out = [
        f"ratio {r:g} is within {keep_away:g} of Omega/omega = 1: the orbit is hard to tell from the "
        "spindle's runout there"
        for r, close in zip(ratios, near_one(ratios, keep_away))
        if close
    ]
    out += [f"ratio {r:g} is outside the drives' band {lo:g} .. {hi:.3g}" for r in ratios if not lo <= r <= hi]
    return out


def _allocated(
    rig, problem, grid, scales, directions: Directions, test=None, reference=None, per_direction: bool = False
) -> dict:
    """The proposal as revolutions per ratio (reduction.allocation): every coefficient's
    standard error at most ``scales`` in the least rig time, with each ratio's adaptive target;
    with a ``test`` (reduction.adequacy_design.ModelTest) the list also keeps the adequacy
    test: K ratios spread over the band, the tested model's errors at most the ``reference``
    list's ((ratios, revolutions, each ratio's directions or None)). ``per_direction``: each
    whirl direction of each ratio is a block of its own (its own count; "whirl" gives each
    entry's direction)."""
    from reduction.allocation import adaptive_targets

    overhead = rig.block_overhead_s
    a = _allocation(problem, grid, scales, directions, overhead, test, reference, per_direction)
    ways = list(a.whirl) if per_direction else directions
    u_kept = problem.noise_at(a.ratios)
    names = problem.spec.names
    base = coefficient_scales_of(problem)
    out = {
        "ratios": list(a.ratios),
        "orbit_hz": [in_hz(r * problem.spin) for r in a.ratios],
        "directions": directions,
        "whirl": [w.value for w in a.whirl] if per_direction else [directions.value] * len(a.ratios),
        "revolutions": list(a.revolutions),
        "target_pct": [
            round(float(t) * 100, 4)
            for t in adaptive_targets(
                problem.spec, problem.theta, problem.spin, problem.radius, a.ratios, a.revolutions, u_kept, ways
            )
        ],
        "identifiable": True,
        "std_errors": {n: float(v) for n, v in zip(names, a.std_errors)},
        "relative_pct": {n: float(v) * 100 for n, v in zip(names, a.std_errors / base)},
        "worst_relative_pct": float(np.max(a.std_errors / base)) * 100,
        "rig_time_s": rig_time(rig, a.ratios, problem.spin, a.revolutions, ways),
    }
    if test is not None:
        out["test_std_errors"] = {n: float(v) for n, v in zip(test.spec.names, a.test_std_errors)}
        out["test_worst_vs_reference"] = a.test_worst
    return out


def _allocation(
    problem, grid, scales, directions: Directions, overhead: float, test, reference, per_direction: bool
) -> Any:
    """reduction.allocation.allocate over ``grid``, or with a ``test`` allocate_keeping_test
    (a TestedAllocation); ``overhead``: s per block besides the revolutions; ``per_direction``:
    the candidates are the grid in each direction (reduction.adequacy_design.per_direction_grid)."""
    from reduction.adequacy_design import allocate_keeping_test, per_direction_grid, spread_shortfall
    from reduction.allocation import allocate
    from reduction.errors import IdentifiabilityError, ReductionError

    try:
        if test is None:
            ratios, ways = per_direction_grid(grid, directions) if per_direction else (grid, directions)
            return allocate(
                problem.spec,
                problem.theta,
                problem.spin,
                problem.radius,
                ratios,
                problem.noise_at(ratios),
                scales,
                block_overhead=overhead,
                directions=ways,
            )
        prior = dict(zip(problem.spec.names, map(float, problem.theta)))
        return allocate_keeping_test(
            test,
            problem.spec,
            prior,
            problem.spin,
            problem.radius,
            grid,
            problem.noise_at,
            reference,
            block_overhead=overhead,
            directions=directions,
            scales=scales,
            per_direction=per_direction,
        )
    except IdentifiabilityError as err:  # the candidate list, the model test's reference
        raise DesignInputError(f"the model test: {err} (or give --no-model-test)") from None
    except ReductionError as err:
        short = None if test is None else spread_shortfall(test, grid)
        if short is not None:  # the grid, not the model: no list of its ratios keeps the test's spread
            raise DesignInputError(_unkept_test(test, short)) from None
        raise DesignInputError(f"no list of the allowed ratios reaches it: {err}") from None


def _unkept_test(test, short: str) -> str:
    """Why no proposal keeps the model test's spread (``short``: reduction.adequacy_design.
    spread_shortfall over the allowed grid), and what to do."""
    from reduction.frequency_list import GRID_STEP

    return (
        f"the model test cannot be kept: the adequacy test of {test.spec.model} {test.spec.freq_dep.text} needs "
        f"{test.frequencies} distinct ratios, one at least in each of {test.frequencies} equal slices of the "
        f"candidate's span, and no list of the allowed ratios (the {GRID_STEP:g} grid of the drives' band) has "
        f"that: {short}. The candidate list identifies the model; give candidate ratios spread wider (slices of "
        f"at least {GRID_STEP:g}: a span of {test.frequencies * GRID_STEP:g} or more), or --no-model-test"
    )


def model_test_object(test, ratios) -> dict:
    """The model-test constraint as stated in the output, and whether ``ratios`` keep it."""
    from reduction.adequacy_design import spread_ok

    return {
        "model": test.spec.model,
        "freq_dep": test.spec.freq_dep.text,
        "frequencies": test.frequencies,
        "band": [test.lo, test.hi],
        "slices": [round(float(v), 6) for v in test.slices()],
        "reason": test.reason(),
        "kept": bool(spread_ok(test, ratios)),
    }


def coefficient_scales_of(problem) -> np.ndarray:
    from reduction.frequency_list import coefficient_scales

    return coefficient_scales(problem.spec, problem.theta, problem.spin)


@dataclass(frozen=True)
class DesignRequest:
    """What `orbitrig design` asks for: the model at a spin, the candidate list of orbit ratios
    and where it came from, the noise and prior, and what the proposal must reach."""

    model: str
    freq_dep: str
    spin_rpm: float
    candidate: list[float]  # orbit ratios |Omega|/omega
    source: str  # where the candidate list came from
    directions: Directions
    radius: float | None  # orbit radius, m; None: the noise's, else 0.1 x clearance
    noise: Any  # orbitrig.cli.design_inputs: stated or measured per-revolution noise
    run: Any  # the run the noise and the prior coefficients were measured in, or None
    lms: LoadSystem
    revolutions: int | None  # per block; None: rig.toml [averaging]
    target: float | None  # worst relative standard error to reach, percent
    keep_away: float  # no proposed ratio this close to 1
    match: bool = False  # reach the candidate's standard errors
    test_models: list | None = None  # (model, freq_dep) pairs whose adequacy test the proposal keeps
    per_direction: bool = False  # the proposal's blocks: each direction of each ratio its own
    #: each candidate ratio's directions (a matrix's [orbit] whirl; candidate ascending), None: ``directions``
    candidate_whirl: list | None = None


def _check_numbers(rig, req: DesignRequest) -> None:
    """DesignInputError naming the first option whose number is out of its range (NaN and
    infinities included): nothing is predicted from it."""
    if not req.spin_rpm > 0:
        raise DesignInputError(f"--spin must be > 0 rpm, got {req.spin_rpm:g}")
    if req.revolutions is not None and req.revolutions < MIN_REVOLUTIONS:
        raise DesignInputError(f"--revolutions {req.revolutions}: at least {MIN_REVOLUTIONS} revolutions per block")
    if req.target is not None and not 0 < req.target < 100:
        raise DesignInputError(f"--target {req.target:g}: a relative standard error in percent, > 0 and < 100")
    clearance = rig.bearing.clearance
    if req.radius is not None and not 0 < req.radius < clearance:
        raise DesignInputError(
            f"--radius {micrometres(req.radius, 'g')}: the orbit radius must be > 0 and below the bearing's "
            f"clearance ({micrometres(clearance, 'g')}, the rig configuration's [bearing])"
        )
    if not 0 <= req.keep_away < math.inf:
        raise DesignInputError(f"--keep-away {req.keep_away:g}: a distance from Omega/omega = 1, finite and >= 0")


def design_object(rig, req: DesignRequest) -> dict:
    """Predict the candidate list, propose one; the JSON object `design --json` prints.
    ``req.test_models``: (model, freq_dep) pairs whose adequacy test the proposal must keep
    (reduction.adequacy_design; the candidate list is the reference); None: no such constraint."""
    from orbitrig.cli.design_inputs import model_check, prior_theta
    from reduction.frequency_list import DesignProblem, predict
    from reduction.models import model_spec

    _check_numbers(rig, req)
    spec = model_spec(req.model, req.freq_dep)
    spin, noise = req.spin_rpm * RPM, req.noise
    radius = req.radius if req.radius is not None else noise.radius or 0.1 * rig.bearing.clearance
    n = req.revolutions or rig.averaging.revolutions
    theta, prior_source = prior_theta(spec, req.run, spin, req.lms)
    problem = DesignProblem(spec, theta, spin, radius, noise.u_revolution, n, req.directions, noise_ratios=noise.ratios)
    grid, lo, hi = _band(rig, req.spin_rpm, req.keep_away)
    cand = predict(problem, req.candidate, None, req.candidate_whirl)
    goal = req.target / 100 if req.target is not None else None
    if goal is not None and req.match:
        raise DesignInputError("give --target or --match, not both")
    out: dict[str, Any] = {
        "model": req.model,
        "freq_dep": spec.freq_dep.text,
        "coefficients": spec.names,
        "units": {name: coefficient_unit(name) for name in spec.names},
        "spin_rpm": req.spin_rpm,
        "orbit_radius_m": radius,
        "directions": req.directions,
        "noise": _noise_object(noise),
        "prior": {"coefficients": dict(zip(spec.names, map(float, theta))), "source": prior_source},
        "allowed": {
            "ratio_min": lo,
            "ratio_max": hi,
            "keep_away_from_1": req.keep_away,
            "grid": list(map(float, grid)),
        },
        "target_pct": req.target,
        "candidate": dict(
            _list_object(rig, problem, cand, n, req.directions, req.candidate_whirl),
            source=req.source,
            warnings=_candidate_warnings(req.candidate, lo, hi, req.keep_away),
        ),
        "match_candidate": req.match,
        "per_direction": req.per_direction,
        "model_test": None,
        "warnings": [],
    }
    out["proposal"], out["model_test"] = _proposal(rig, problem, cand, grid, req, n=n, goal=goal)
    prop, ratios = out["proposal"], list(cand.ratios)
    few = len(prop["ratios"]) < MIN_RATIOS  # the sweep refuses a matrix of fewer orbit frequencies
    prop["warnings"] = [f"one ratio: a matrix needs {MIN_RATIOS} at least, so no sweep runs this list"] if few else []
    lists = [(ratios, n, out["candidate"]["whirl"]), (prop["ratios"], prop["revolutions"], prop["whirl"])]
    warning = model_check(spec, req.run, spin, req.lms, problem, *lists)
    out["warnings"] = [warning] if warning else []
    return out


def _proposal(rig, problem, cand, grid, req: DesignRequest, *, n: int, goal):
    """(the proposed list, the model test it keeps or None). With ``goal`` (relative standard
    error) or ``req.match`` (the candidate's errors ``cand``): revolutions per ratio reaching it in
    the least rig time; else the best list of as many ratios as the candidate at ``n`` revolutions."""
    from reduction.frequency_list import propose

    directions, candidate, match = problem.directions, req.candidate, req.match
    if not (match or goal):
        if req.per_direction:
            raise DesignInputError("--per-direction: give --match or --target (it allocates revolutions per block)")
        best = propose(problem, grid, count=len(candidate), block_overhead=rig.block_overhead_s)
        return _list_object(rig, problem, best.best, n, directions), None
    if cand.std_errors is None and match:
        raise DesignInputError(f"--match: there is nothing to match: {cand.refusal}")
    scales = cand.std_errors if match else coefficient_scales_of(problem) * goal
    test = _model_test(req.test_models, candidate)
    reference = (candidate, n, req.candidate_whirl)
    allocated = _allocated(rig, problem, grid, scales, directions, test, reference, req.per_direction)
    proposal = dict(allocated, reaches_target=True)
    return proposal, None if test is None else model_test_object(test, proposal["ratios"])


def _model_test(test_models, candidate):
    from reduction.adequacy_design import model_test
    from reduction.errors import ReductionError

    if test_models is None:
        return None
    try:
        return model_test(list(test_models), candidate)
    except ReductionError as err:
        raise DesignInputError(f"the model test: {err} (or give --no-model-test)") from None
