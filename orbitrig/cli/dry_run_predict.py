"""`sweep --dry-run`: the predicted uncertainty of each configured model, and which ones the
planned orbits cannot identify.

For every model of the matrix and every distinct (spin, orbit radius) of its operating
points: the Cramer-Rao standard errors (reduction.frequency_list.predict) of circular orbits
at the matrix's ratios, each in its directions (the blocks the plan runs), for the stated per-revolution noise and the nominal
prior of `orbitrig design` (orbitrig.cli.design_inputs), averaged over the revolutions each
ratio's blocks take (:func:`block_revolutions`: the per-ratio counts, else the fixed count,
else an adaptive rule's minimum). One line per model: the worst relative standard error over the operating points (and where), or why
the planned orbits cannot identify it (reduction.identifiability.check_plan).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from orbitrig.config import RPM
from rigunits import micrometres

#: a predicted relative standard error above this (a fraction) leaves a coefficient undetermined
UNDETERMINED = 1.0


@dataclass(frozen=True)
class ModelPrediction:
    """One configured model: worst relative standard error (fraction) over the operating
    points, with the coefficient, spin (rpm) and radius (m) where it occurs; or a refusal."""

    label: str
    worst: float | None
    coefficient: str | None
    spin_rpm: float | None
    radius: float | None
    best: float | None
    refusal: str | None = None
    #: coefficient -> (lowest, highest) predicted relative standard error over the (spin,
    #: radius) where it exceeds UNDETERMINED, and at how many of them
    undetermined: dict[str, tuple[float, float, int]] = field(default_factory=dict)
    fits: int = 0  # planned (spin, radius) fits predicted


def block_revolutions(rig, mat) -> list[int]:
    """Revolutions the prediction assumes per ratio (order of ``mat.orbit.ratio_list``): the
    per-ratio counts ([orbit] revolutions; with [averaging] each ratio's expected count held
    within min..max), else the fixed count, else an adaptive rule's minimum (pessimistic)."""
    k = range(len(mat.orbit.ratio_list))
    if mat.orbit.revolutions is not None:
        return [mat.expected_revolutions(i) for i in k]
    if mat.averaging is not None:
        return [mat.averaging.min_revolutions for _ in k]
    return [mat.fixed_revolutions(i, rig.averaging.revolutions) for i in k]


def adaptive_line(rig, mat) -> str | None:
    """With [averaging]: the acquisition time if every block stopped at the minimum, and at
    the maximum (the plan's durations assume each ratio's expected count, else the maximum)."""
    from orbitrig.run.plan import acquisition_time, operating_points
    from rigunits import format_duration

    a = mat.averaging
    if a is None:
        return None
    orbits = [b.orbit for p in operating_points(mat, rig) for b in p.blocks]
    lo = sum(acquisition_time(w, a.min_revolutions) for w in orbits)
    hi = sum(acquisition_time(w, a.max_revolutions) for w in orbits)
    targets = mat.orbit.target_pct
    target = f"{a.target_pct:g} %" if targets is None else f"its ratio's target ({min(targets):g}..{max(targets):g} %)"
    assumed = "the maximum" if mat.orbit.revolutions is None else "each ratio's expected revolutions"
    return (
        f"adaptive averaging: every channel <= {target} in {a.min_revolutions}..{a.max_revolutions} "
        f"revolutions per block: acquiring takes {format_duration(lo)} .. {format_duration(hi)} "
        f"(the estimate above assumes {assumed})"
    )


def predict_model(rig, mat, model: str, freq_dep: str, noise) -> ModelPrediction:
    """The prediction line of one configured model (see the module doc)."""
    from orbitrig.cli.design_inputs import prior_theta
    from orbitrig.config import orbit_hz
    from reduction.errors import IdentifiabilityError
    from reduction.frequency_list import DesignProblem, predict
    from reduction.identifiability import check_plan
    from reduction.models import model_spec, parse_freq_dep

    label = f"{model} {freq_dep}"
    ratios, whirl = mat.orbit.ratio_list, mat.orbit.whirl_list  # the planned blocks (orbitrig.run.plan)
    spins = sorted(set(mat.operating.spin_rpm))
    try:
        for rpm in spins:
            check_plan(model, freq_dep, orbit_hz(ratios, rpm), whirl)
    except IdentifiabilityError as err:
        return ModelPrediction(label, None, None, None, None, None, str(err).splitlines()[0])
    if parse_freq_dep(freq_dep).auto:
        return ModelPrediction(label, None, None, None, None, None)
    spec = model_spec(model, freq_dep)
    theta, _ = prior_theta(spec)
    n = block_revolutions(rig, mat)
    rows: list[tuple[float, str, float, float]] = []
    over: dict[str, tuple[float, float, int]] = {}
    for rpm in spins:
        for eps in sorted(set(mat.operating.dynamic_eccentricity)):
            radius = eps * rig.bearing.clearance
            p = predict(DesignProblem(spec, theta, rpm * RPM, radius, noise.u_revolution, n[0]), ratios, n, whirl)
            if p.relative is None:  # singular information: nothing identifiable at this point
                rows.append((np.inf, "every coefficient", rpm, radius))
                continue
            j = int(np.argmax(p.relative))
            rows.append((p.worst, spec.names[j], rpm, radius))
            for name, rel in zip(spec.names, p.relative):
                if rel > UNDETERMINED:
                    lo, hi, count = over.get(name, (np.inf, 0.0, 0))
                    over[name] = (min(lo, float(rel)), max(hi, float(rel)), count + 1)
    worst = max(rows)
    return ModelPrediction(label, worst[0], worst[1], worst[2], worst[3], min(rows)[0], None, over, len(rows))


def prediction_lines(rig, mat) -> list[str]:
    """The dry run's prediction block (one header line, one line per model)."""
    from orbitrig.cli.design_inputs import stated_noise

    noise = stated_noise()
    n = block_revolutions(rig, mat)
    adaptive = adaptive_line(rig, mat)
    out = [adaptive] if adaptive else []
    if mat.orbit.revolutions is not None and mat.orbit.per_direction:  # each entry's ratio and directions
        o = mat.orbit
        each = ", ".join(f"{r:g} {w.value} {k}" for r, w, k in zip(o.ratio_list, o.whirl_list, n))
        counts = f"revolutions per entry of the list: {each}" + (" (the expected counts)" if adaptive else "")
    elif mat.orbit.revolutions is not None:
        counts = ", ".join(map(str, n)) + " revolutions per ratio" + (" (the expected counts)" if adaptive else "")
    else:
        counts = f"{n[0]} revolutions per block" + (", the adaptive minimum" if adaptive else "")
    out.append(
        f"predicted uncertainty (Cramer-Rao; noise {noise.source}; {counts}; nominal prior coefficients; "
        "`orbitrig design` proposes lists):"
    )
    for m in mat.models:
        p = predict_model(rig, mat, m.model, m.freq_dep, noise)
        if p.refusal:
            out.append(f"  {p.label}: CANNOT be identified from the planned orbits: {p.refusal}")
        elif p.worst is None:
            out.append(f"  {p.label}: identifiable (the exponent is chosen at identification; not predicted)")
        else:
            assert p.best is not None and p.radius is not None  # predicted with the worst
            out.append(
                f"  {p.label}: worst relative standard error {p.worst * 100:.3g} % ({p.coefficient} at "
                f"{p.spin_rpm:g} rpm, orbit radius {micrometres(p.radius, '.3g')}); best point {p.best * 100:.3g} %"
            )
            out += undetermined_lines(p)
    return out


def undetermined_lines(p: ModelPrediction) -> list[str]:
    """'    UNDETERMINED: ...' naming each coefficient of a planned fit predicted above 100 % (each
    kept on one line by orbitrig.cli.plain_table.wrap)."""
    from orbitrig.cli.plain_table import unbroken

    if not p.undetermined:
        return []
    parts = [
        unbroken(
            f"{name} {lo * 100:.3g}..{hi * 100:.3g} % ({n} of {p.fits})"
            if n > 1
            else f"{name} {lo * 100:.3g} % ({n} of {p.fits})"
        )
        for name, (lo, hi, n) in p.undetermined.items()
    ]
    return [
        f"    UNDETERMINED: predicted relative standard error over {UNDETERMINED * 100:g} % (planned fits "
        f"per spin and orbit radius): {', '.join(parts)}; more revolutions, a wider ratio range or "
        "`orbitrig design` may help, else drop the model"
    ]
