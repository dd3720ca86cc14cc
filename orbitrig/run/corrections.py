"""What the sweep corrects from the active calibration record (docs/calibration.md).

- Forces: each force channel's lag behind the probes (``[delay]``: phase and time delay)
  taken out, then each load measuring system's 2 x 2 gain matrix (``[loads.<system>]``;
  identity without one), f_journal = G f_read, per revolution and on the averaged phasors.
  A channel's sign is its gains' (rig.toml's and G's), never a lag: a recorded phase nearer
  +-180 deg than 0 (a reversed channel, written so before the delay step told the two apart)
  turns the channel by its difference from +-180 deg only.
- Probes: the runout of each probe track at 1x and 2x spin (``[runout]``) taken out of every
  block's per-revolution phasors, the block's spin phase fitted from its own revolutions
  (reduction.runout) and the runout turned through them at the block's spin turns per board
  revolution: the ratio fitted from the block's own samples when it is resolved, else the
  commanded spin over the orbit speed as written to the drives (spin_turns, reduction.runout_slip.fit_spin_turns:
  fitted once per block by the point's analysis, the runout's basis at it built once a block,
  Corrections.runout_basis, and handed to the subtraction and to its uncertainty);
  only when the rig configuration's ``subtract_runout`` is true (default).
  Then each probe's lag behind the four probes' mean (``[delay.<probe>]``, a record with
  ``probe_lags_corrected``; an older one leaves it in the readings, counted in its uncertainty)
  taken out as the force channels' (reduction.calibration.correct_lag), and each probe's gain
  (``[probes]``, from known displacement steps).

Every lag is taken out at one orbit speed per block, block_orbit_speed: the measured one
(2 pi over the mean period of the block's revolutions on the A/D board's clock), the planned
one only when none was measured; a block's revolutions and its average alike (the board keeps
no revolution more than the averaging rule's speed tolerance off the set speed, and the
revolutions' own periods are not stored), so the mean of a block's corrected revolutions is
its corrected average.

The blocks keep what was read; the orbit tables (and so every identification and the stored
tables) hold the corrected values. SI.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from daq.frames import slot_angle
from orbitrig.config import LMS, RigConfig
from orbitrig.config import PROBE_CHANNELS as PROBES
from orbitrig.load_systems import LoadSystem
from orbitrig.store.records import BlockRecord
from reduction.calibration import correct_forces, correct_lag, polarity_and_lag

# MIN_REVOLUTIONS: fewer, the block left as read (a plan refuses it)
from reduction.runout import MIN_REVOLUTIONS, RunoutBasis, removal_changes, remove_runout, runout_basis
from reduction.runout_slip import SpinTurns, counts_spin_turns, unfitted_turns
from rigunits import US


def spin_turns(rec: BlockRecord, ch: dict[str, int], spin: float) -> SpinTurns:
    """Block ``rec``'s spin turns per board revolution: commanded (BlockRecord.commanded_turns: spin
    over |Omega| as written to the drives, ``spin`` (rad/s) over the planned |Omega| when not
    known), and fitted from its four probes' samples (reduction.runout_slip.counts_spin_turns; not
    fitted, u inf, for fewer than MIN_REVOLUTIONS revolutions or no samples of each). A fit of the
    whole block (0.5 to 2 ms): a point's analysis makes it once per block and hands it on."""
    commanded = rec.commanded_turns(spin)
    counts = np.asarray(rec.raw_counts)
    n = len(rec.record_phasors)
    if n < MIN_REVOLUTIONS or counts.ndim != 3 or counts.shape[0] != n:
        return unfitted_turns(commanded)
    idx = [ch[p] for p in PROBES]
    theta = slot_angle(np.asarray(rec.slots)[idx])
    gains, offsets = np.asarray(rec.gains)[idx], np.asarray(rec.offsets)[idx]
    return counts_spin_turns(counts[:, idx, :], gains, offsets, theta, commanded, _revolutions(rec))


def _revolutions(rec: BlockRecord) -> np.ndarray:
    """(N,) the board's revolution numbers of the block's revolutions (consecutive when not stored)."""
    return np.arange(len(rec.record_phasors)) if rec.revolutions is None else np.asarray(rec.revolutions)


def block_orbit_speed(rec: BlockRecord) -> float:
    """|Omega| (rad/s) at which block ``rec`` is corrected and tabled: its measured orbit speed
    when finite and > 0, else the planned |Omega|."""
    w = rec.measured_orbit_speed
    return w if math.isfinite(w) and w > 0 else abs(rec.block.orbit)


@dataclass(frozen=True)
class Corrections:
    force_gains: dict[LoadSystem, np.ndarray] = field(default_factory=dict)
    runout: np.ndarray | None = None  # (4, 2) complex, m: PROBES x (1x, 2x spin)
    lags: dict[str, tuple[float, float]] = field(default_factory=dict)  # force channel -> (lag rad, delay s), no sign
    probe_gains: dict[str, float] = field(default_factory=dict)  # probe -> gain (1)
    probe_lags: dict[str, tuple[float, float]] = field(default_factory=dict)  # probe -> (lag rad, delay s)
    runout_u: np.ndarray | None = None  # (4, 2) m: the runout's standard uncertainties (None: not recorded)

    @classmethod
    def of_rig(cls, rig: RigConfig) -> "Corrections":
        """The corrections of ``rig``'s active record (none without one)."""
        rec = rig.record
        if rec is None:
            return cls()
        runout, runout_u = None, None
        if rec.runout is not None and rig.subtract_runout:
            runout = np.array([rec.runout.phasors(p) for p in PROBES])
            runout_u = rec.runout.uncertainties(PROBES)
        lags = {name: (polarity_and_lag(np.radians(d.phase_deg))[1], d.delay_us * US) for name, d in rec.delay.items()}
        gains = {p: g.gain for p, g in rec.probes.items()}
        turned = {p: lags[p] for p in PROBES if p in lags} if rec.probe_lags_corrected else {}
        forces = {name: lag for name, lag in lags.items() if name not in PROBES}
        systems = {lms: rec.force_gain(lms) for lms in LMS if lms in rec.loads}
        return cls(systems, runout, forces, gains, turned, runout_u)

    def forces(
        self, lms: LoadSystem, fx: np.ndarray, fy: np.ndarray, orbit: np.ndarray | float
    ) -> tuple[np.ndarray, np.ndarray]:
        """(fx, fy) of system ``lms`` corrected: each channel's lag at |orbit| (rad/s, broadcast
        against the phasors; a block's: block_orbit_speed) taken out, then the gain matrix."""
        lag_x, lag_y = self.lags.get(f"fx_{lms}"), self.lags.get(f"fy_{lms}")
        fx = fx if lag_x is None else correct_lag(fx, np.asarray(orbit), *lag_x)
        fy = fy if lag_y is None else correct_lag(fy, np.asarray(orbit), *lag_y)
        gain = self.force_gains.get(lms)
        return (fx, fy) if gain is None else correct_forces(gain, fx, fy)

    def runout_basis(self, rec: BlockRecord, ch: dict[str, int], turns: SpinTurns) -> RunoutBasis | None:
        """Block ``rec``'s runout basis at ``turns``' used ratio (its spin_turns;
        reduction.runout.runout_basis): built once a block and handed to probes and runout_changes.
        None without a runout subtracted or for a block too short for the spin phase's fit."""
        if self.runout is None or len(rec.record_phasors) < MIN_REVOLUTIONS:
            return None
        theta = slot_angle(np.asarray(rec.slots)[[ch[p] for p in PROBES]])
        return runout_basis(theta, turns.used, _revolutions(rec), self.runout.shape[1])

    def probes(self, rec: BlockRecord, ch: dict[str, int], basis: RunoutBasis | None) -> tuple[np.ndarray, np.ndarray]:
        """((C,) averaged, (N, C) per-revolution) phasors of the block, the probes' runout taken out
        once, placed by ``basis`` (the block's runout_basis; None: none taken out), then their lags (at
        block_orbit_speed, the average's as its revolutions') and gains applied; the average is the
        stored one plus the mean of the corrected revolutions less that of the read ones."""
        rp = np.asarray(rec.record_phasors)
        without = self._without_runout(rec, ch, basis)
        shift = (without - rp).mean(axis=0) if len(rp) else 0.0
        orbit = block_orbit_speed(rec)
        mean = self._lags_and_gains(np.asarray(rec.phasors) + shift, ch, orbit)
        return mean, self._lags_and_gains(without, ch, orbit)

    def probe_phasors(self, rec: BlockRecord, ch: dict[str, int], basis: RunoutBasis | None) -> np.ndarray:
        """(C,) the block's averaged phasors as Corrections.probes corrects them."""
        return self.probes(rec, ch, basis)[0]

    def runout_changes(self, rec: BlockRecord, ch: dict[str, int], basis: RunoutBasis | None) -> np.ndarray | None:
        """(Q, C) change of the block's corrected averaged phasors (probe_phasors) when the runout
        subtracted moves by one standard uncertainty of each source, Q = 4 probes x 2 harmonics x
        (re, im) in that order, each part u / sqrt(2) of the recorded complex u; the spin phase
        fitted again, placed by ``basis`` (the block's runout_basis, as probes took it;
        reduction.runout.removal_changes), then the probes' lags and gains. None without a runout
        subtracted or its uncertainties; zeros for a block too short for the fit (no basis)."""
        rp = np.asarray(rec.record_phasors)
        if self.runout is None or self.runout_u is None:
            return None
        out = np.zeros((2 * self.runout.size, rp.shape[1]), dtype=complex)
        if basis is None:
            return out
        idx = [ch[p] for p in PROBES]
        steps = self.runout_u / np.sqrt(2)
        changes = removal_changes(rp[:, idx], self.runout, basis, steps)
        out[:, idx] = changes.reshape(-1, len(idx))
        return self._lags_and_gains(out, ch, block_orbit_speed(rec))

    def _without_runout(self, rec: BlockRecord, ch: dict[str, int], basis: RunoutBasis | None) -> np.ndarray:
        rp = np.asarray(rec.record_phasors)
        if self.runout is None or basis is None:
            return rp
        idx = [ch[p] for p in PROBES]
        out = rp.copy()
        out[:, idx] = remove_runout(rp[:, idx], self.runout, basis)
        return out

    def _lags_and_gains(self, values: np.ndarray, ch: dict[str, int], orbit: float) -> np.ndarray:
        """``values`` (..., C) with each probe's column brought in step with the four probes' mean
        at ``orbit`` (rad/s; after the runout, which is as the probe read it) and through its gain."""
        if not self.probe_gains and not self.probe_lags:
            return values
        out = np.array(values, dtype=complex, copy=True)
        for p, lag in self.probe_lags.items():
            out[..., ch[p]] = correct_lag(out[..., ch[p]], np.asarray(orbit), *lag)
        for p, g in self.probe_gains.items():
            out[..., ch[p]] *= g
        return out
