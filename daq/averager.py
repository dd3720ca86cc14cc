"""Streaming synchronous average of trigger-aligned revolutions, fixed or adaptive. Pure.

The average of N revolutions is taken slot by slot (time-synchronous average
locked to the orbit trigger). Every revolution's fundamental phasor is computed
as it arrives (one weighted sum per channel, the least-squares weights of
``reduction.fourier.phasor`` at the channel's own angles), so that

- an adaptive rule can stop the block once every channel's averaged phasor is
  known well enough (running sums, O(channels) per revolution), and
- coherence between channels can be computed from the records
  (``reduction.coherence``).

The block keeps the raw int16 counts of exactly the revolutions it averaged,
(N, C, S), with their calibration; memory is bounded by the rule's maximum.

Phasor convention: q(theta) = dc + Re(q_bar e^{i theta}) + ..., theta = 2 pi slot / 360
(orbit angle after the trigger). Standard uncertainty of the averaged phasor (the
orbit table's ``u_*``): u = sqrt(sum_r |q_r - q_bar|^2 / (n - 1)) / sqrt(n); with the
rule's ``spin_turns`` the spin tones' leakage is fitted out of that scatter
(reduction.noise.mean_uncertainty) at the block's spin turns per revolution: with the rule's
``probes``, the ratio fitted from their samples (reduction.runout_slip.counts_spin_turns, as the
sweep's analysis fits it) once it is resolved, else the commanded one; the live check fits it
again each time the block grew by REFIT_GROWTH, the block's own u from all its revolutions
(AveragedBlock.turns says which ratio it used). Each revolution's spin harmonics, what the ratio
is fitted from, are computed once as it arrives (reduction.runout_slip.revolution_harmonics): a
fit on the loop that reads the board costs O(revolutions) small numbers, not all their samples.

The numerics are reduction's (phasor weights, the running scatter, the tones' fit, the ratio's
fit); when a block is complete is the rule's (daq.averaging_rule.AveragingRule); this module
applies it as the revolutions arrive and keeps them.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from daq.averaging_rule import AveragingRule, StopReason
from daq.frames import slot_angle
from daq.revolutions import Revolution, RevolutionBatch
from daq.stats import AcquisitionStats
from reduction.fourier import harmonic_fit, phasor_weights
from reduction.noise import RunningScatter, mean_uncertainty, phasor_uncertainty, prefix_mean_uncertainty
from reduction.runout_slip import MIN_REVOLUTIONS, SpinTurns, harmonics_spin_turns, revolution_harmonics, unfitted_turns

#: the live fit of a block's spin ratio is made again once its revolutions grew by this fraction
REFIT_GROWTH = 0.1


@dataclass(frozen=True)
class AveragedBlock:
    """Synchronous average of N good revolutions, engineering units (SI): gain * counts + offset.

    orbit_speed: |Omega| (rad/s) = 2 pi / mean period over the block (NaN if no period
    was measured). slots, theta (= 2 pi slots / 360 rad), mean: (C, S); mean is
    ``raw_counts.mean(axis=0) * gains[:, None] + offsets[:, None]``. phasors: (C,)
    complex fundamental of the average; uncertainty: (C,) its standard uncertainty
    from the scatter of record_phasors (inf for N = 1). record_phasors: (N, C).
    rms_residual: (C,) RMS of the average minus (dc + fundamental). dc: (C,).
    raw_counts: (N, C, S) int16. revs, t_us: (N,) board revolution numbers and
    trigger times (us); periods: (N,) s (NaN where unknown). stop_reason: why it
    stopped (StopReason). stats: this block's counters (drops per reason). turns: the spin
    turns per revolution its uncertainty took the spin tones out at (``used``: fitted when
    resolved, else the commanded; None without the rule's spin_turns).
    """

    orbit_speed: float
    slots: np.ndarray
    theta: np.ndarray
    mean: np.ndarray
    phasors: np.ndarray
    uncertainty: np.ndarray
    record_phasors: np.ndarray
    rms_residual: np.ndarray
    dc: np.ndarray
    raw_counts: np.ndarray
    gains: np.ndarray
    offsets: np.ndarray
    revs: np.ndarray
    t_us: np.ndarray
    periods: np.ndarray
    stop_reason: StopReason
    rule: AveragingRule
    stats: AcquisitionStats = field(default_factory=AcquisitionStats)
    turns: SpinTurns | None = None

    @property
    def n_revolutions(self) -> int:
        return len(self.revs)

    @property
    def n_records(self) -> int:
        return len(self.revs)

    @property
    def drop_reasons(self) -> dict[str, int]:
        return dict(self.stats.drop_reasons)

    @property
    def relative_uncertainty(self) -> np.ndarray:
        """(C,) uncertainty / |phasors| (inf for a zero phasor)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            rel: np.ndarray = self.uncertainty / np.abs(self.phasors)
        return rel


class StreamingAverager:
    """Average consecutive good revolutions in blocks decided by ``rule``
    (an ``AveragingRule``, or an int n for ``AveragingRule.fixed(n)``).

    ``gains``/``offsets`` (per channel, unit/count and unit) convert counts to
    engineering units; default 1 and 0 (raw counts). ``take`` consumes revolutions
    up to the end of the current block; ``push``/``push_batch`` return every
    completed block and start the next one.
    """

    def __init__(
        self,
        rule: AveragingRule | int = 50,
        gains: Sequence[float] | None = None,
        offsets: Sequence[float] | None = None,
    ) -> None:
        if not isinstance(rule, AveragingRule):  # a count: the fixed rule
            if int(rule) != rule or rule < 1:
                raise ValueError(f"n_revolutions must be an integer >= 1, not {rule}")
            rule = AveragingRule.fixed(int(rule))
        self.rule = rule
        self._gains = None if gains is None else np.asarray(gains, np.float64)
        self._offsets = None if offsets is None else np.asarray(offsets, np.float64)
        for name, v in (("gains", self._gains), ("offsets", self._offsets)):
            if v is not None and not np.all(np.isfinite(v)):
                raise ValueError(f"{name} must be finite, got {v.tolist()}")
        hi = rule.max_revolutions
        self._counts = np.zeros((0, 0, 0), np.int16)  # (max, C, S) int16: the block's revolutions (none: no layout yet)
        self._records = np.zeros((hi, 0), complex)  # (max, C) per-revolution phasors
        self._revs, self._t_us = np.zeros(hi, np.int64), np.zeros(hi, np.int64)
        self._periods = np.zeros(hi)
        self._slots = np.zeros((0, 0), np.int64)
        self._weights = np.zeros((0, 0), complex)
        self._cal = (np.zeros(0), np.zeros(0))
        self._running = RunningScatter()
        self._n = 0
        self._turns: tuple[int, SpinTurns] | None = None  # (revolutions, the spin ratio fitted from them)
        self._harmonics = np.zeros((len(rule.probes), 2, hi), complex)  # (P, 2, max) each revolution's spin 1x, 2x

    @property
    def n_revolutions(self) -> int:
        """The most revolutions a block can hold."""
        return self.rule.max_revolutions

    @property
    def count(self) -> int:
        """Revolutions in the block being built."""
        return self._n

    def push(self, rev: Revolution) -> AveragedBlock | None:
        period = np.nan if rev.period_s is None else rev.period_s
        batch = RevolutionBatch(
            np.array([rev.rev]), np.array([rev.t_us]), np.array([period]), rev.counts[None], rev.slots
        )
        blocks = self.push_batch(batch)
        return blocks[0] if blocks else None

    def push_batch(self, revs: RevolutionBatch) -> list[AveragedBlock]:
        blocks, i = [], 0
        while i < len(revs):
            used, block = self.take(revs.take(slice(i, None)))
            i += used
            if block is not None:
                blocks.append(block)
        return blocks

    def take(self, revs: RevolutionBatch) -> tuple[int, AveragedBlock | None]:
        """Add revolutions from the start of ``revs`` until the block is complete.
        Returns (revolutions used, the completed block or None)."""
        if not len(revs):
            return 0, None
        self._prepare(revs.counts.shape[1:], revs.slots)
        seg = revs.take(slice(0, self.rule.max_revolutions - self._n))
        records = np.einsum("rcs,cs->rc", seg.counts, self._weights) * self._cal[0]
        harmonics = self._revolution_harmonics(seg)
        used, reason = self._stop(records, seg, harmonics)
        n0, n1 = self._n, self._n + used
        self._counts[n0:n1] = seg.counts[:used]
        self._harmonics[:, :, n0:n1] = harmonics[:, :, :used]
        self._records[n0:n1] = records[:used]
        self._revs[n0:n1], self._t_us[n0:n1] = seg.rev[:used], seg.t_us[:used]
        self._periods[n0:n1] = seg.period_s[:used]
        self._n = n1
        return used, (self._finish(reason) if reason is not None else None)

    def _prepare(self, shape: tuple[int, int], slots: np.ndarray) -> None:
        """Buffers and phasor weights for this scan layout (a new layout starts a new block)."""
        if self._counts.shape[1:] == shape and np.array_equal(slots, self._slots):
            return
        c, s = shape
        for name, v in (("gains", self._gains), ("offsets", self._offsets)):
            if v is not None and v.shape != (c,):
                raise ValueError(f"{name} has {v.size} values for {c} channels")
        self._cal = (
            np.ones(c) if self._gains is None else self._gains,
            np.zeros(c) if self._offsets is None else self._offsets,
        )
        self._counts = np.empty((self.rule.max_revolutions, c, s), np.int16)
        self._records = np.empty((self.rule.max_revolutions, c), complex)
        self._slots = np.array(slots)
        self._weights = phasor_weights(slot_angle(self._slots))
        self._running.reset()
        self._n, self._turns = 0, None

    def _revolution_harmonics(self, seg: RevolutionBatch) -> np.ndarray:
        """(P, 2, R) the probes' spin harmonics of each revolution of ``seg`` at the commanded
        ratio (none without the rule's spin_turns and probes)."""
        rule, p = self.rule, list(self.rule.probes)
        if rule.spin_turns is None or not p:
            return np.zeros((len(p), 2, len(seg)), complex)
        gains, offsets = self._cal
        return revolution_harmonics(seg.counts[:, p], gains[p], offsets[p], slot_angle(self._slots[p]), rule.spin_turns)

    def _stop(self, records: np.ndarray, seg: RevolutionBatch, harmonics: np.ndarray) -> tuple[int, StopReason | None]:
        """How many of these new per-revolution phasors (R, C) (of the revolutions ``seg``, their
        probes' spin ``harmonics``) the block takes, and why it stops (None: not yet)."""
        rule, r = self.rule, len(records)
        room = rule.max_revolutions - self._n
        if rule.target is not None:
            if rule.spin_turns is not None:
                turns = self._spin_turns((seg, harmonics), self._n + r >= rule.min_revolutions)
                used = self._first_met_tones(records, seg.rev, rule.target, turns.used)
            else:
                used = self._running.first_met(records, rule.target, rule.min_revolutions)
            if used:
                self._running.add(records[:used])
                return used, StopReason.TARGET
            self._running.add(records[:room])
        if r >= room:
            return room, StopReason.COUNT if rule.target is None else StopReason.MAX
        return r, None

    def _first_met_tones(self, records: np.ndarray, revs_new: np.ndarray, target: float, spin_turns: float) -> int:
        """Like RunningScatter.first_met with the spin tones fitted out (rule.spin_turns)."""
        rule = self.rule
        every = np.concatenate([self._records[: self._n], records])
        revs = np.concatenate([self._revs[: self._n], revs_new])
        u = prefix_mean_uncertainty(every, spin_turns, start=self._n, revolutions=revs)
        m = self._n + 1 + np.arange(len(records))
        mean = np.abs(np.cumsum(every, axis=0)[self._n :] / m[:, None])
        ok = np.all(u <= target * mean, axis=1) & (m >= max(rule.min_revolutions, 2))
        hit = np.flatnonzero(ok)
        return int(hit[0]) + 1 if len(hit) else 0

    def _spin_turns(self, new: tuple[RevolutionBatch, np.ndarray] | None, due: bool) -> SpinTurns:
        """The block's spin turns per revolution with the revolutions ``new`` (and their probes'
        spin harmonics; None: none, the block's end) added: fitted from the probes' harmonics of
        every revolution when ``due`` and the block grew by REFIT_GROWTH since the last fit, and
        always at its end unless the last fit was of all its revolutions; else the last fit (the
        commanded ratio before the first)."""
        rule, n0, last = self.rule, self._n, self._turns
        assert rule.spin_turns is not None
        n = n0 + (0 if new is None else len(new[0]))
        if last is not None and (n == last[0] or (new is not None and n < last[0] * (1 + REFIT_GROWTH))):
            return last[1]
        if not rule.probes or not due:
            why = "no probe channels named" if not rule.probes else "too few revolutions yet"
            return SpinTurns(rule.spin_turns, float("nan"), float("inf"), why) if last is None else last[1]
        harmonics, revs = self._harmonics[:, :, :n0], self._revs[:n0]
        if new is not None:
            harmonics, revs = np.concatenate([harmonics, new[1]], axis=2), np.concatenate([revs, new[0].rev])
        fit = (
            harmonics_spin_turns(harmonics, rule.spin_turns, revs)
            if n >= MIN_REVOLUTIONS
            else unfitted_turns(rule.spin_turns)
        )
        self._turns = (n, fit)
        return fit

    def _finish(self, reason: StopReason) -> AveragedBlock:
        n = self._n
        turns = None if self.rule.spin_turns is None else self._spin_turns(None, True)
        gains, offsets = self._cal
        theta = slot_angle(self._slots)
        counts = self._counts[:n].copy()
        mean = counts.mean(axis=0) * gains[:, None] + offsets[:, None]
        fit = harmonic_fit(mean, theta)
        records = self._records[:n].copy()
        periods = self._periods[:n].copy()
        known = periods[~np.isnan(periods)]
        speed = 2 * np.pi / known.mean() if len(known) else float("nan")
        self._n, self._turns = 0, None
        self._running.reset()
        return AveragedBlock(
            orbit_speed=float(speed),
            slots=self._slots.copy(),
            theta=theta,
            mean=mean,
            phasors=fit.phasor,
            uncertainty=(
                phasor_uncertainty(records, axis=0)
                if turns is None
                else mean_uncertainty(records, turns.used, self._revs[:n])
            ),
            record_phasors=records,
            rms_residual=fit.rms_residual,
            dc=fit.mean,
            raw_counts=counts,
            gains=gains.copy(),
            offsets=offsets.copy(),
            revs=self._revs[:n].copy(),
            t_us=self._t_us[:n].copy(),
            periods=periods,
            stop_reason=reason,
            rule=self.rule,
            turns=turns,
        )
