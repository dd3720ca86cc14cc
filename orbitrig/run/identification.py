"""From averaged blocks to a point's results: block records, orbit tables, K C D (truth: run.truth).

Pure (no I/O): the engine calls these in a worker thread; the synthetic-run
fixtures of the tests call `identify_operating_point` directly.

Phasors: q = Re(q_bar e^{i Omega t}); the journal's motion is the probe-plane
average of the two probes of each axis (x_a, x_b and y_a, y_b).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from orbitrig.config import LMS, CalibrationUncertainty, ModelSpec, RigConfig
from orbitrig.config import PROBE_CHANNELS as PROBES
from orbitrig.load_systems import LoadSystem
from orbitrig.run.corrections import Corrections, block_orbit_speed, spin_turns
from orbitrig.run.steps import Block
from orbitrig.run.point_analysis import analyse_point
from orbitrig.run.calibration_dof import CalibrationDof
from daq.averager import AveragedBlock
from orbitrig.run.model_truth import model_truth
from orbitrig.run.truth import true_impedance
from orbitrig.store.records import BlockRecord, IdentificationEntry, PointResults
from reduction.arrays import ComplexArray
from reduction.coherence import orbit_coherences
from reduction.errors import ReductionError
from reduction.noise import mean_uncertainty
from reduction.identify import identify
from reduction.result import Identification
from reduction.runout import RunoutBasis
from reduction.runout_slip import SpinTurns
from reduction.systematic import DisplacementTerm
from reduction.table import OrbitTable


def probe_plane(values: np.ndarray, ch: dict[str, int]) -> tuple[np.ndarray, np.ndarray]:
    """(x, y) at the bearing's mid-plane: the mean of the a and b probes of each axis,
    over the last axis of `values` (channels)."""
    v = np.asarray(values)
    return (v[..., ch["x_a"]] + v[..., ch["x_b"]]) / 2, (v[..., ch["y_a"]] + v[..., ch["y_b"]]) / 2


def block_record(
    block: Block, blk: AveragedBlock, rig: RigConfig, written: tuple[float, float] = (math.nan, math.nan)
) -> BlockRecord:
    """What is stored for one block: the average, its raw counts, the coherences of each
    load measuring system (rows piezo, strain; columns xfx, yfx, xfy, yfy) and the speeds
    ``written`` to the drives (rad/s, spin and signed orbit; nan: not known)."""
    ch = rig.channel_index
    rp = np.asarray(blk.record_phasors)
    x, y = probe_plane(rp, ch)
    coh = np.array([orbit_coherences(x, y, rp[:, ch[f"fx_{lms}"]], rp[:, ch[f"fy_{lms}"]]) for lms in LMS])
    stats = {k: v for k, v in blk.stats.to_dict().items() if isinstance(v, (int, float, dict))}
    return BlockRecord(
        block=block,
        measured_orbit_speed=float(blk.orbit_speed),
        raw_counts=blk.raw_counts,
        slots=blk.slots,
        gains=np.asarray(blk.gains),
        offsets=np.asarray(blk.offsets),
        mean=np.asarray(blk.mean),
        record_phasors=rp,
        phasors=np.asarray(blk.phasors),
        dc=np.asarray(blk.dc),
        rms_residual=np.asarray(blk.rms_residual),
        coherence=coh,
        stats=stats,
        uncertainty=np.asarray(blk.uncertainty),
        uncertainty_turns=blk.turns,
        n_records=blk.n_records,
        stop_reason=blk.stop_reason,
        revolutions=np.asarray(blk.revs),
        written=written,
    )


def identify_operating_point(
    spin: float,
    recs: list[BlockRecord],
    ch: dict[str, int],
    models: Sequence[ModelSpec],
    truth: dict[str, Any] | None = None,
    calibration: CalibrationUncertainty | None = None,
    corrections: Corrections | None = None,
    dof: CalibrationDof | None = None,
) -> PointResults:
    """One operating point's results: the orbit table of each load measuring system (forward
    and backward blocks together; ``corrections``, the active calibration record's force gain
    matrices and probe runout, applied), every model of ``models`` (ModelSpec) identified on each
    (a refused model keeps its reason), each fit judged (orbitrig.run.point_analysis: the
    uncertainty budget from the rig's stated ``calibration`` uncertainty, model adequacy, the
    two systems' consistency, derived quantities; ``dof`` the calibration's degrees of freedom,
    orbitrig.run.calibration_dof), and the two systems' forces compared.
    With a simulator's ``truth`` every fit also stores its own truth (run.model_truth)."""
    recs = sorted(recs, key=lambda r: (r.block.freq, -r.block.direction))
    corr = corrections or Corrections()
    turns = [spin_turns(r, ch, spin) for r in recs]  # the one fit of each block's spin ratio
    bases = runout_bases(recs, ch, corr, turns)  # the one build of each block's runout basis
    probes = corrected_probes(recs, ch, corr, bases)
    tables: dict[LoadSystem, OrbitTable] = {lms: orbit_table(spin, recs, ch, lms, corr, probes, turns) for lms in LMS}
    idents: dict[tuple[LoadSystem, str], IdentificationEntry] = {}
    fits: dict[tuple[LoadSystem, str], Identification] = {}
    for lms in LMS:
        for spec in models:
            try:
                res = identify(tables[lms], model=spec.model, freq_dep=spec.freq_dep, method=spec.method)
            except ReductionError as err:
                idents[(lms, spec.key)] = {"spec": spec, "error": str(err)}
                continue
            fits[(lms, spec.key)] = res
            idents[(lms, spec.key)] = {"spec": spec, "json": res.to_dict()}
            if truth is not None and "Z_re" in truth:
                idents[(lms, spec.key)]["json"]["truth"] = model_truth(res, tables[lms], true_impedance(truth))
    grid = np.unique([abs(r.block.orbit) for r in recs])  # the planned orbit frequencies, rad/s
    dof = dof or CalibrationDof()
    runout = runout_term(recs, ch, corr, bases) if calibration is not None else None
    runout = None if runout is None else dataclasses.replace(runout, dof=dof.runout)
    analyse_point(spin, tables, fits, idents, calibration, grid, runout, dof)
    return PointResults(tables, idents, lms_comparison(recs, ch, corr), truth, runout_turns=runout_turns(recs, turns))


def runout_bases(
    recs: Sequence[BlockRecord], ch: dict[str, int], corrections: Corrections, turns: Sequence[SpinTurns]
) -> list[RunoutBasis | None]:
    """Per block its runout basis at its ``turns`` (Corrections.runout_basis; None: no runout
    taken out): built once, for corrected_probes and runout_term alike."""
    return [corrections.runout_basis(r, ch, t) for r, t in zip(recs, turns)]


def corrected_probes(
    recs: Sequence[BlockRecord],
    ch: dict[str, int],
    corrections: Corrections,
    bases: Sequence[RunoutBasis | None],
) -> list[tuple[ComplexArray, ComplexArray]]:
    """Per block (averaged phasors, per-revolution phasors) with the probes corrected
    (Corrections.probes), the runout placed by the block's basis (runout_bases)."""
    return [corrections.probes(r, ch, b) for r, b in zip(recs, bases)]


def runout_turns(recs: Sequence[BlockRecord], fits: Sequence[SpinTurns]) -> dict[str, Any]:
    """Per block (the orbit table's row order) the spin turns per board revolution the runout is
    placed with, ``fits`` (orbitrig.run.corrections.spin_turns of each block): commanded, fitted
    (None when not), its standard uncertainty u (None when not fitted), whether the fit is
    resolved and so ``used`` (its difference from the commanded above
    reduction.runout_slip.RESOLVED u), and why a block has none ("" when fitted); all turns per
    revolution (1)."""

    def number(v: float) -> float | None:
        return float(v) if np.isfinite(v) else None

    return {
        "orbit_hz": [r.block.orbit_hz for r in recs],
        "direction": [r.block.direction for r in recs],
        "commanded": [f.commanded for f in fits],
        "fitted": [number(f.fitted) for f in fits],
        "u": [number(f.u) for f in fits],
        "resolved": [f.resolved for f in fits],
        "used": [f.used for f in fits],
        "unfitted": [f.unfitted for f in fits],
    }


def runout_term(
    recs: Sequence[BlockRecord],
    ch: dict[str, int],
    corrections: Corrections,
    bases: Sequence[RunoutBasis | None],
) -> DisplacementTerm | None:
    """The subtracted runout's standard uncertainties as errors of the orbit table's x, y common to
    every block of the point (reduction.systematic.DisplacementTerm; None without a runout taken
    out or without its recorded uncertainties): for each probe, harmonic and part (re, im, each
    u / sqrt(2) of the recorded complex u) the change of each row's (x, y) when the runout
    subtracted moves by that much, every block corrected again by its basis (runout_bases, the
    one its probes were corrected with; Corrections.runout_changes)."""
    changes = [corrections.runout_changes(r, ch, b) for r, b in zip(recs, bases)]
    if not changes or any(c is None for c in changes):
        return None
    x, y = probe_plane(np.array(changes), ch)  # (n, Q) each
    labels = [f"{p}.runout{h}.{part}" for p in PROBES for h in (1, 2) for part in ("re", "im")]
    return DisplacementTerm(labels, np.stack([x, y], axis=1))


def orbit_table(
    spin: float,
    recs: list[BlockRecord],
    ch: dict[str, int],
    lms: LoadSystem,
    corrections: Corrections | None = None,
    probes: list[tuple[ComplexArray, ComplexArray]] | None = None,
    turns: Sequence[SpinTurns] | None = None,
) -> OrbitTable:
    """Orbit table of one point for one load measuring system (Omega > 0, direction in the phasors),
    with each row's revolution count and the standard uncertainty of its phasors
    (reduction.noise.mean_uncertainty of the per-revolution x, y, fx, fy: the scatter with the
    spin tones' rotating leakage taken out at the block's spin turns per board revolution, the
    ratio its runout is placed with: ``turns``' used, each block's orbitrig.run.corrections.spin_turns,
    fitted here when not given); the forces through the ``corrections`` (lags and gain matrix; None:
    as read); ``probes`` per block (averaged phasors, per-revolution phasors) with the runout taken
    out (None: as read)."""
    probes = probes or [(r.phasors, r.record_phasors) for r in recs]
    turns = turns if turns is not None else [spin_turns(r, ch, spin) for r in recs]
    corr = corrections or Corrections()
    ph = np.array([p for p, _ in probes])
    orbit = np.array([block_orbit_speed(r) for r in recs])  # the revolutions' and the average's alike
    x, y = probe_plane(ph, ch)
    n_records = np.array([len(r.record_phasors) for r in recs])
    # each block's revolutions as the table holds them (runout out, forces corrected): their
    # uncertainty and their coherences
    revs = [block_revolutions(r, rp, ch, lms, corr) for r, (_, rp) in zip(recs, probes)]
    u = np.array([mean_uncertainty(np.stack(v, axis=1), t.used, r.revolutions) for r, v, t in zip(recs, revs, turns)])
    gamma2 = np.array([orbit_coherences(*v) for v in revs])
    fx, fy = corr.forces(lms, ph[:, ch[f"fx_{lms}"]], ph[:, ch[f"fy_{lms}"]], orbit)
    return OrbitTable(
        spin=spin,
        orbit=orbit,
        x=x,
        y=y,
        fx=fx,
        fy=fy,
        gamma2=gamma2.reshape(len(recs), 4),
        n_records=n_records,
        u=u if np.all(np.isfinite(u)) else None,
    )


def block_revolutions(
    rec: BlockRecord, record_phasors: ComplexArray, ch: dict[str, int], lms: LoadSystem, corrections: Corrections
) -> tuple[ComplexArray, ComplexArray, ComplexArray, ComplexArray]:
    """(x, y, fx, fy) of each revolution of block ``rec`` as its orbit-table row holds them
    (their mean is the row): ``record_phasors`` (the probes corrected, Corrections.probes)
    and system ``lms``'s forces through ``corrections`` at the block's one speed, block_orbit_speed."""
    correct = functools.partial(corrections.forces, lms, orbit=block_orbit_speed(rec))
    return per_revolution(record_phasors, ch, lms, correct)


def per_revolution(
    record_phasors: ComplexArray,
    ch: dict[str, int],
    lms: LoadSystem,
    correct: Callable[[ComplexArray, ComplexArray], tuple[ComplexArray, ComplexArray]] | None = None,
) -> tuple[ComplexArray, ComplexArray, ComplexArray, ComplexArray]:
    """(x, y, fx, fy) of each revolution (m, m, N, N): the probe-plane means and system ``lms``'s
    forces, through ``correct(fx, fy) -> (fx, fy)`` when given."""
    rp = np.asarray(record_phasors)
    x, y = probe_plane(rp, ch)
    fx, fy = rp[:, ch[f"fx_{lms}"]], rp[:, ch[f"fy_{lms}"]]
    if correct is not None:
        fx, fy = correct(fx, fy)
    return x, y, fx, fy


def lms_comparison(
    recs: list[BlockRecord], ch: dict[str, int], corrections: Corrections | None = None
) -> dict[str, Any]:
    """Strain vs piezo forces per block (each through its ``corrections``): amplitude ratio and
    phase difference (deg)."""
    out: dict[str, Any] = {"orbit_hz": [r.block.orbit_hz for r in recs], "direction": [r.block.direction for r in recs]}
    ph = np.array([r.phasors for r in recs]) if recs else np.zeros((0, len(ch)), complex)
    corr, orbit = corrections or Corrections(), np.array([block_orbit_speed(r) for r in recs])
    forces: dict[LoadSystem, dict[str, ComplexArray]] = {
        lms: dict(zip(("fx", "fy"), corr.forces(lms, ph[:, ch[f"fx_{lms}"]], ph[:, ch[f"fy_{lms}"]], orbit)))
        for lms in LMS
    }
    for f in ("fx", "fy"):
        ratio = forces[LoadSystem.STRAIN][f] / forces[LoadSystem.PIEZO][f]
        out[f"{f}_amp_ratio"] = np.abs(ratio).round(6).tolist()
        out[f"{f}_phase_diff_deg"] = np.degrees(np.angle(ratio)).round(4).tolist()
    amp = np.abs(np.array(out["fx_amp_ratio"] + out["fy_amp_ratio"]) - 1) * 100
    ph = np.abs(np.array(out["fx_phase_diff_deg"] + out["fy_phase_diff_deg"]))
    out["max_amp_diff_pct"] = round(float(amp.max()), 4) if amp.size else None
    out["max_phase_diff_deg"] = round(float(ph.max()), 4) if ph.size else None
    return out
