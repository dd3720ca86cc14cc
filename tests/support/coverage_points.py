"""The paper's Table 1 point measured many times over, fast: the simulator's own signal path
(bearing, chains, disturbances, quantisation; sim.revolutions, no transport) gives each
block's revolutions, and the sweep's own point step (orbitrig.run.identification: block
records, orbit tables, identification, budget, truth per model) reduces them. The wire
protocols, drives and storage are what the sweep tests cover; this covers the numbers of
many seeds in seconds.

A seed is a new measurement of a newly calibrated rig: new noise, and calibration errors drawn
from the rig's stated calibration uncertainty (config/rig.toml [calibration_uncertainty]) in
place of the scenario's fixed ones. Over the seeds the expanded interval (95.45 %) then means
what it says: it should cover the truth about 95 % of the time, neither far less (a budget
that misses an error) nor always (a budget that overstates them).

Units SI; spin and orbits rad/s."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from types import SimpleNamespace

import numpy as np

from orbitrig.config import ModelSpec, load_rig
from orbitrig.run.identification import block_record, identify_operating_point
from orbitrig.run.steps import Block
from orbitrig.run.truth import point_truth
from sim.config import CHANNEL_GAINS
from sim.scenario_files import load_sim_config
from sim.fits import constant_fit, power_fit
from sim.physics import RigPhysics
from sim.revolutions import revolution_phasors, simulate_revolutions

from support.paths import ROOT

SCENARIOS = {
    "paper": "config/sim.toml",
    "clean": "config/sim/clean.toml",
    "compressible": "config/sim/compressible.toml",
}
#: the paper's Table 1 operating point
SPIN = 1000.0 * 2 * math.pi / 60
TABLE1 = dict(recess_pressure=0.4826e6, pressure_ratio=0.25, static_eccentricity=0.0)
ECCENTRICITY = 0.04  # eps_d: orbit radius / clearance
REVOLUTIONS = 50


def table1_physics(cfg) -> RigPhysics:
    """The simulated rig (a sim.config.SimConfig) set to the paper's Table 1 point: eps_d 0.04,
    eps_s 0, p_r 0.4826 MPa, beta 0.25."""
    physics = RigPhysics(cfg)
    physics.set_manual(orbit_radius=ECCENTRICITY * cfg.geometry.clearance, **TABLE1)
    return physics


MODELS = [ModelSpec(model="kc8"), ModelSpec(model="kcd11")]


class PhysicsTruth:
    """The orbitrig.run.rig_io.TruthSource of a RigPhysics (what simulated_rig's adapter gives)."""

    def __init__(self, physics: RigPhysics):
        self.physics = physics

    def impedance(self, spin: float, orbits) -> np.ndarray:
        return self.physics.impedances(spin, orbits)

    def reference_fits(self, spin: float, orbits) -> dict:
        z = self.physics.impedances(spin, orbits)
        return {"constant": constant_fit(orbits, z), "power": power_fit(orbits, z)}


@dataclass(frozen=True)
class _Stats:
    def to_dict(self) -> dict:
        return {}


def _averaged(physics: RigPhysics, orbit: float, n: int, t0: float) -> SimpleNamespace:
    """The daq averager's block (the fields block_record reads) of n revolutions at `orbit`."""
    slots, values = simulate_revolutions(physics, SPIN, orbit, n, t0=t0)
    gains = np.asarray(CHANNEL_GAINS)
    values = np.round(values / gains[:, None]) * gains[:, None]  # the board's counts
    rp = revolution_phasors(slots, values)
    return SimpleNamespace(
        orbit_speed=abs(orbit),
        raw_counts=np.zeros((0,) + values.shape[1:], np.int16),
        slots=slots,
        gains=gains,
        offsets=np.zeros(len(gains)),
        mean=values.mean(axis=0),
        record_phasors=rp,
        phasors=rp.mean(axis=0),
        dc=values.mean(axis=(0, 2)),
        rms_residual=np.zeros(len(gains)),
        stats=_Stats(),
        uncertainty=np.zeros(len(gains)),
        n_records=n,
        stop_reason="count",
        revs=np.arange(n),
        turns=None,  # no averaging rule: the stored u took no spin ratio
    )


def calibrated(cfg, stated, rng: np.random.Generator):
    """``cfg`` with its chain's calibration errors drawn from the stated uncertainties, as the
    budget models them (reduction.systematic; orbitrig.run.point_analysis.lms_calibration): a
    gain per force channel; per axis one displacement gain, shared by its a and b probes (the
    budget takes them as fully correlated) and carrying that axis' own sensitivity error; each
    load measuring system's phase lag (common to its fx and fy: the simulator's structure) and
    the force channels' delay (common to the four). The probes' stated phase and delay have no
    counterpart in the simulator. The scenario's anti-alias filters stay."""
    names = list(cfg.adc.channels)
    gain = {n: float(rng.normal(0.0, stated.channel(n).gain)) for n in names if n.startswith("f")}
    for axis in "xy":
        a, b = stated.channel(f"{axis}_a").gain, stated.channel(f"{axis}_b").gain
        gain[f"{axis}_a"] = gain[f"{axis}_b"] = float(
            rng.normal(0.0, math.hypot((a + b) / 2, stated.probe_sensitivity))
        )
    chain = replace(
        cfg.chain,
        enabled=True,
        gain_error=tuple(gain[n] for n in names),
        probe_sensitivity_error=0.0,
        force_delay=float(rng.normal(0.0, stated.channel("fx_piezo").delay)),
        filter_cutoff=cfg.chain.filter_cutoff if cfg.chain.enabled else (0.0,) * len(names),
    )
    lms = replace(
        cfg.lms,
        piezo_gain_error=0.0,
        strain_gain_error=0.0,
        piezo_phase_lag=float(rng.normal(0.0, stated.channel("fx_piezo").phase)),
        strain_phase_lag=float(rng.normal(0.0, stated.channel("fx_strain").phase)),
    )
    return replace(cfg, chain=chain, lms=lms)


def measured_point(scenario: str, seed: int, ratios):
    """The sweep's results (orbitrig.store.records.PointResults: identifications
    {(lms, key): {"spec", "json"}}, truth) of one measurement of the Table 1 point at `ratios`
    (Omega/omega, forward and backward) on `scenario`, seed `seed`."""
    rig = load_rig(ROOT / "config/rig.toml")
    cfg = load_sim_config(ROOT / SCENARIOS[scenario])
    cfg = calibrated(replace(cfg, seed=seed), rig.calibration_uncertainty, np.random.default_rng([seed, 7]))
    physics = table1_physics(cfg)
    recs, t0 = [], 0.0
    for i, ratio in enumerate(ratios):
        for direction in (1, -1):
            orbit = direction * ratio * SPIN
            blk = _averaged(physics, orbit, REVOLUTIONS, t0)
            t0 += REVOLUTIONS * 2 * math.pi / abs(orbit)
            recs.append(block_record(Block(freq=i, direction=direction, orbit=orbit), blk, rig))
    truth = point_truth(SimpleNamespace(spin=SPIN), recs, PhysicsTruth(physics))
    return identify_operating_point(SPIN, recs, rig.channel_index, MODELS, truth, rig.calibration_uncertainty)


def covered(stored: dict) -> tuple[int, int, list[str]]:
    """(entries covered, entries, the missed ones) of one stored fit: each free K, C, D entry
    whose expanded uncertainty U (combined, at its k: rig.toml's typed-in calibration u count as
    exactly known) reaches its own truth."""
    d = stored["json"]
    truth, u = d["truth"]["coefficients"], d["expanded_uncertainty"]["values"]
    assert d["expanded_uncertainty"]["basis"] == "combined"
    missed = [k for k in d["free"] if abs(d["coefficients"][k] - truth[k]) > u[k]]
    return len(d["free"]) - len(missed), len(d["free"]), missed
