"""The runout placed at each block's own spin turns per board revolution (docs/calibration.md,
Limits): the two spindles are not phase-locked, so the spin turns a fraction s off its command;
the sweep fits the ratio from the block's samples (reduction.runout_slip.fit_spin_turns: the spin
harmonics' phase drift against the orbit's revolutions) and places the runout with it when it is
resolved, the commanded ratio otherwise (orbitrig.run.corrections.spin_turns).

On the simulator's own signals (sim.revolutions: the clean scenario's film, probe noise, bearing
tones, speed ripple and the board's slot-edge sampling; the probe tracks' runout 1 µm at 1x and
0.4 µm at 2x, a 1 µm orbit), quantised to counts as the board gives them and corrected as the
sweep corrects a block (Corrections.probe_phasors): the runout left in a block's mean is the
corrected mean less the same block simulated without runout (the same seed: the same noise)."""

from __future__ import annotations

import dataclasses
import json
import math

import h5py
import numpy as np
import pytest

from orbitrig.run.calibration_measure import runout_of
from orbitrig.run.corrections import Corrections, spin_turns
from orbitrig.config import LMS, CalibrationUncertainty, ModelSpec
from orbitrig.run.identification import identify_operating_point, orbit_table, per_revolution, runout_turns
from orbitrig.run.steps import Block
from orbitrig.store.pieces import write_results
from orbitrig.store.records import BlockRecord, PointResults
from reduction.fourier import phasor
from reduction.runout import removal_changes, remove_runout, runout_basis
from reduction import runout_slip
from reduction.runout_slip import RESOLVED
from sim.scenario_files import load_sim_config
from sim.physics import RigPhysics
from sim.revolutions import simulate_revolutions
from support.paths import ROOT
from tests.support.phasor_blocks import CH

RPM = 2 * math.pi / 60
SLOT = 2 * math.pi / 360
SPIN = 1000 * RPM  # commanded, rad/s
PROBES = ("x_a", "y_a", "x_b", "y_b")
IDX = [CH[p] for p in PROBES]
GAINS = np.array([0.1, 0.1, 0.1, 0.1, 5e-9, 5e-9, 5e-9, 5e-9])  # clean.toml's board: N or m per count
RUNOUT = (1e-6, 0.4e-6)  # m, the probe tracks' runout at 1x and 2x spin
#: (orbit / spin ratio, revolutions) of the draws: the Monte Carlo's blocks
CASES = [(0.471, 6), (0.733, 6), (0.471, 25), (0.733, 25)]
DRAWS = 4  # per case: seeds and start times


def _physics(seed: int, runout: tuple[float, float]) -> RigPhysics:
    base = load_sim_config(ROOT / "config/sim/clean.toml")
    physics = RigPhysics(dataclasses.replace(base, seed=seed, noise=dataclasses.replace(base.noise, runout=runout)))
    physics.set_manual(orbit_radius=1e-6, static_eccentricity=0.0)
    return physics


def _record(physics: RigPhysics, slip: float, ratio: float, n: int, t0: float, drop: int | None) -> BlockRecord:
    """A forward block at orbit ``ratio`` x the commanded spin, the spin turning ``slip`` fast, of
    ``n`` revolutions (revolution ``drop`` left out, as the averager drops a damaged one)."""
    slots, v = simulate_revolutions(physics, SPIN * (1 + slip), ratio * SPIN, n, t0=t0)
    counts = np.round(v / GAINS[None, :, None]).astype(np.int16)
    keep = np.array([k != drop for k in range(n)])
    counts = counts[keep]
    values = counts * GAINS[None, :, None]
    theta = slots * SLOT
    rp = np.array([[phasor(values[k, c], theta[c]) for c in range(8)] for k in range(len(counts))])
    zeros = np.zeros(8)
    return BlockRecord(
        Block(0, 1, ratio * SPIN), ratio * SPIN, counts, slots, GAINS, zeros, values.mean(axis=0), rp, rp.mean(axis=0),
        zeros, zeros, np.zeros((2, 4)), revolutions=np.arange(n)[keep],
    )  # fmt: skip


def _runout(seed: int) -> np.ndarray:
    """(4, 2) complex, m: the runout a slow roll of the scenario of ``seed`` (its runout's phases) records."""
    base = load_sim_config(ROOT / "config/sim/clean.toml")
    quiet = dataclasses.replace(base.noise, runout=RUNOUT, probe_white=0.0, bearing_probe=0.0, line_probe=0.0)
    physics = RigPhysics(dataclasses.replace(base, seed=seed, noise=dataclasses.replace(quiet, speed_ripple=0.0)))
    physics.set_manual(orbit_radius=0.0, static_eccentricity=0.0)
    slots, v = simulate_revolutions(physics, 100 * RPM, 100 * RPM, 8)
    return np.array([runout_of(v[:, k, :], 1.0, 0.0, slots[k] * SLOT)[0] for k in IDX])


@pytest.fixture(scope="module")
def runouts() -> dict[int, np.ndarray]:
    return {seed: _runout(seed) for seed in range(1, DRAWS + 1)}


def _left(runouts: dict[int, np.ndarray], slip: float) -> tuple[np.ndarray, np.ndarray, list]:
    """Over the Monte Carlo's draws: the largest |runout left| (m) in a block's corrected mean,
    new (the sweep's Corrections) and old (the commanded ratio), per draw; and each block's fit."""
    new, old, fits = [], [], []
    for ratio, n in CASES:
        for seed, runout in runouts.items():
            corr = Corrections(runout=runout)
            drop = 3 if seed == 2 else None
            rec = _record(_physics(seed, RUNOUT), slip, ratio, n, 0.17 * seed, drop)
            truth = _record(_physics(seed, (0.0, 0.0)), slip, ratio, n, 0.17 * seed, drop).phasors[IDX]
            rp, theta = rec.record_phasors[:, IDX], rec.slots[IDX] * SLOT
            commanded = rp - remove_runout(rp, runout, runout_basis(theta, 1 / ratio, rec.revolutions, 2))
            old.append(np.max(np.abs(rec.phasors[IDX] - commanded.mean(axis=0) - truth)))
            at = spin_turns(rec, CH, SPIN)
            new.append(np.max(np.abs(corr.probe_phasors(rec, CH, corr.runout_basis(rec, CH, at))[IDX] - truth)))
            fits.append((at, (1 + slip) / ratio))
    return np.array(new), np.array(old), fits


@pytest.mark.timeout(60)
@pytest.mark.parametrize(("slip", "old_least", "new_most"), [(0.001, 3e-9, 1.5e-9), (0.005, 12e-9, 1.5e-9)])
def test_a_slipping_spin_leaves_next_to_no_runout_in_a_blocks_mean(runouts, slip, old_least, new_most):
    new, old, fits = _left(runouts, slip)
    # 80 draws: the commanded ratio left 1.2 to 5.7 nm (0.1 %) and 7.6 to 27 nm (0.5 %), medians 3.0
    # and 12 nm; the fitted one 0.27 and 0.25 nm (at most 1.1 and 0.7), as at s = 0 (median 0.23,
    # at most 1.0 nm: the spin-phase fit's own noise)
    assert old.max() > old_least, old
    assert new.max() < new_most, new
    assert np.median(new) < np.median(old) / 5, (new, old)
    for fit, true in fits:  # every block's ratio resolved, within 5 u of the truth (80 draws: |z| rms 1.3 to 1.5)
        assert fit.resolved and fit.used == fit.fitted, fit
        assert abs(fit.fitted - true) < 5 * fit.u and fit.u < 1e-4 * true, (fit, true)


@pytest.mark.timeout(60)
def test_without_slip_the_block_is_corrected_as_at_the_commanded_ratio(runouts):
    new, old, fits = _left(runouts, 0.0)
    # equal within noise: an unresolved ratio corrects exactly as before (80 draws: 1 resolved, 0.08 nm apart)
    assert np.max(np.abs(new - old)) < 0.2e-9, (new, old)
    assert new.max() < 1.5e-9
    assert sum(f.resolved for f, _ in fits) <= 2, fits
    for fit, true in fits:
        assert abs(fit.fitted - true) < 5 * fit.u, (fit, true)


def test_the_runout_terms_sensitivities_follow_the_ratio_the_block_is_corrected_at(runouts):
    """removal_changes (the runout term's columns) through the same fitted ratio as the subtraction."""
    runout = runouts[1]
    rec = _record(_physics(1, RUNOUT), 0.005, 0.733, 25, 0.3, None)
    corr = Corrections(runout=runout, runout_u=np.full((4, 2), 30e-9))
    at = spin_turns(rec, CH, SPIN)
    got = corr.runout_changes(rec, CH, corr.runout_basis(rec, CH, at))
    assert got is not None
    rp, theta, steps = rec.record_phasors[:, IDX], rec.slots[IDX] * SLOT, np.full((4, 2), 30e-9 / np.sqrt(2))
    assert at.resolved
    fitted = removal_changes(rp, runout, runout_basis(theta, at.used, rec.revolutions, 2), steps).reshape(-1, 4)
    assert np.allclose(got[:, IDX], fitted, rtol=0, atol=1e-15)
    true = removal_changes(rp, runout, runout_basis(theta, 1.005 / 0.733, rec.revolutions, 2), steps).reshape(-1, 4)
    assert np.max(np.abs(got[:, IDX] - true)) < 0.02 * np.max(np.abs(true))


def test_each_blocks_fitted_ratio_is_recorded_with_the_points_results(tmp_path):
    recs = [_record(_physics(1, RUNOUT), 0.005, 0.733, 25, 0.3, None)]
    recs.append(dataclasses.replace(recs[0], raw_counts=np.zeros((0, 8, 45), np.int16)))  # no samples: not fitted
    turns = runout_turns(recs, [spin_turns(r, CH, SPIN) for r in recs])
    assert turns["commanded"] == [pytest.approx(1 / 0.733)] * 2
    assert turns["fitted"][0] == pytest.approx(1.005 / 0.733, abs=5 * turns["u"][0]) and turns["u"][0] < 1e-4
    assert turns["resolved"] == [True, False] and turns["used"] == [turns["fitted"][0], turns["commanded"][1]]
    assert turns["fitted"][1] is None and turns["u"][1] is None and "no samples" in turns["unfitted"][1]
    assert abs(turns["fitted"][0] - turns["commanded"][0]) > RESOLVED * turns["u"][0]
    with h5py.File(tmp_path / "results.h5", "w") as f:
        write_results(f, PointResults({}, {}, {}, runout_turns=turns))
    with h5py.File(tmp_path / "results.h5", "r") as f:
        assert json.loads(f["runout_turns"].attrs["json"]) == turns


@pytest.mark.parametrize("seed", [1, 2])
def test_a_blocks_uncertainty_takes_its_spin_tones_out_at_the_ratio_its_runout_is_placed_with(seed):
    """The orbit table's u of a block whose probes read the runout (none subtracted), the spin 0.5 %
    fast, 60 revolutions at orbit ratio 0.471: the scatter without the spin tones fitted at the
    block's used ratio, plus their share of the mean. The reference is the same block's u without
    runout (the same seed: the same noise) with what the runout leaves in its mean added."""
    on = _record(_physics(seed, RUNOUT), 0.005, 0.471, 60, 0.3, None)
    off = _record(_physics(seed, (0.0, 0.0)), 0.005, 0.471, 60, 0.3, None)
    assert spin_turns(on, CH, SPIN).resolved
    lms = LMS[0]
    got = orbit_table(SPIN, [on], CH, lms).u
    quiet = orbit_table(SPIN, [off], CH, lms).u
    assert got is not None and quiet is not None
    x_on, y_on = per_revolution(on.record_phasors, CH, lms)[:2]
    x_off, y_off = per_revolution(off.record_phasors, CH, lms)[:2]
    left = np.abs([x_on.mean() - x_off.mean(), y_on.mean() - y_off.mean()])  # m: the runout's share of the mean
    ref = np.hypot(quiet[0, :2], left)  # 0.6 to 0.7 nm
    # at the commanded ratio the runout's 1x turned 0.5 % off the fitted tone: u_x, u_y 14 to 15 nm
    # (21 to 26 x the reference); at the used ratio 0.96 to 1.17 x
    assert np.all(got[0, :2] < 1.5 * ref) and np.all(got[0, :2] > 0.67 * ref), (got[0, :2], ref)
    assert np.allclose(got[0, 2:], quiet[0, 2:], rtol=0.05), (got[0, 2:], quiet[0, 2:])  # forces: no runout


def test_a_points_analysis_fits_each_blocks_spin_ratio_once(runouts, monkeypatch):
    """identify_operating_point with a runout and its u subtracted (the probes' phasors and
    revolutions, both systems' tables' u, the runout term, runout_turns) fits each block's spin
    ratio once (0.5 to 2 ms a fit; six a block before) and places everything at that one fit."""
    fitted: list[int] = []
    harmonics = runout_slip._spin_harmonics

    def counted(values, theta, turns, h, orbit):
        fitted.append(np.shape(values)[1])
        return harmonics(values, theta, turns, h, orbit)

    monkeypatch.setattr(runout_slip, "_spin_harmonics", counted)
    recs = [_record(_physics(1, RUNOUT), 0.005, ratio, 12, 0.3, None) for ratio in (0.471, 0.733, 0.9)]
    recs = [dataclasses.replace(r, block=Block(i, 1, r.block.orbit)) for i, r in enumerate(recs)]
    corr = Corrections(runout=runouts[1], runout_u=np.full((4, 2), 30e-9))
    stated = CalibrationUncertainty(probe_sensitivity_pct=0.1)
    res = identify_operating_point(SPIN, recs, CH, [ModelSpec(model="kcd11")], None, stated, corr)
    assert len(fitted) == len(recs), fitted  # one fit of each block's 12 revolutions
    turns = res.runout_turns
    assert turns is not None and all(turns["resolved"]), turns
    for used, rec in zip(turns["used"], sorted(recs, key=lambda r: r.block.freq)):
        assert used == pytest.approx(1.005 * SPIN / rec.block.orbit, rel=1e-4)


def test_the_commanded_ratio_is_the_speeds_as_written_to_the_drives_the_planned_in_an_older_run():
    """No slip: the drives turn at their REF counts, 1000.05 and 649.95 rpm for the planned 1000 and
    650 (0.15 rpm a count). Against the planned ratio, 1.538462, the block's fit (1.538657, u
    1.2e-6: 100 revolutions, a 1 µm runout) is resolved, 170 u off; against the written one, as the
    sweep stores it with the block, it is not (within 1 u)."""
    planned, written = (SPIN, 0.65 * SPIN), (1000.05 * RPM, 649.95 * RPM)
    turned = _record(_physics(1, RUNOUT), written[0] / SPIN - 1, written[1] / SPIN, 100, 0.3, None)
    rec = dataclasses.replace(turned, block=Block(0, 1, planned[1]))  # the plan's block
    old = spin_turns(rec, CH, SPIN)  # a block stored before the written speeds were: the planned ratio
    assert old.commanded == pytest.approx(planned[0] / planned[1], rel=1e-12)
    assert old.fitted == pytest.approx(written[0] / written[1], abs=3 * old.u) and old.u < 2e-6
    assert old.resolved and abs(old.fitted - old.commanded) > 150 * old.u
    new = spin_turns(dataclasses.replace(rec, written=written), CH, SPIN)
    assert new.commanded == pytest.approx(1000.05 / 649.95, rel=1e-12)
    assert not new.resolved and new.used == new.commanded and new.fitted == pytest.approx(old.fitted, abs=new.u)
    assert abs(new.fitted - new.commanded) < new.u  # against 170 u off the planned
