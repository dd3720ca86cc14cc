"""Streaming synchronous average of trigger-aligned revolutions. Pure.

The average of N revolutions is taken slot by slot (time-synchronous average
locked to the orbit trigger). Each revolution's fundamental phasor is kept so
that coherence between channels can be computed from the records
(``reduction.coherence``). Memory is bounded by N: the block's N revolutions in
counts, (N, C, S) int16, reused from block to block.

Phasor convention: q(theta) = dc + Re(q_bar e^{i theta}) + ..., theta = 2 pi slot / 360
(orbit angle after the trigger), fitted at each channel's own angles by
``reduction.fourier`` (sequential mode: channel k at slots k, k+C, ...).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from daq.revolutions import Revolution, RevolutionBatch
from daq.stats import AcquisitionStats
from reduction.fourier import harmonic_fit, phasor


@dataclass(frozen=True)
class AveragedBlock:
    """Synchronous average of N good revolutions, engineering units (gain * counts + offset).

    orbit_speed: |Omega| (rad/s) = 2 pi / mean period over the block (NaN if no
    period was measured). theta, mean: (C, S). phasors: (C,) complex fundamental
    of the average. record_phasors: (N, C) fundamental of each revolution.
    rms_residual: (C,) RMS of the average minus (dc + fundamental). dc: (C,).
    revs: (N,) the board's revolution numbers that went into the average.
    """

    orbit_speed: float
    theta: np.ndarray
    mean: np.ndarray
    phasors: np.ndarray
    record_phasors: np.ndarray
    rms_residual: np.ndarray
    dc: np.ndarray
    stats: AcquisitionStats = field(default_factory=AcquisitionStats)
    revs: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))

    @property
    def n_revolutions(self) -> int:
        return len(self.record_phasors)


class StreamingAverager:
    """Average consecutive good revolutions in blocks of ``n_revolutions``.

    ``gains``/``offsets`` (per channel, unit/count and unit) convert counts to
    engineering units; default 1 and 0 (raw counts). ``push``/``push_batch`` return
    each completed block and start the next one.
    """

    def __init__(self, n_revolutions: int = 50, gains: Sequence[float] | None = None,
                 offsets: Sequence[float] | None = None) -> None:
        if n_revolutions < 1:
            raise ValueError(f"n_revolutions must be >= 1, not {n_revolutions}")
        self.n_revolutions = n_revolutions
        self._gains = None if gains is None else np.asarray(gains, np.float64)
        self._offsets = None if offsets is None else np.asarray(offsets, np.float64)
        self._counts: np.ndarray | None = None  # (N, C, S) int16: the block's revolutions
        self._revs = np.zeros(n_revolutions, np.int64)
        self._periods = np.zeros(n_revolutions)
        self._n = 0

    @property
    def count(self) -> int:
        """Revolutions in the block being built."""
        return self._n

    def push(self, rev: Revolution) -> AveragedBlock | None:
        period = np.nan if rev.period_s is None else rev.period_s
        batch = RevolutionBatch(np.array([rev.rev]), np.array([rev.t_us]), np.array([period]),
                                rev.counts[None], rev.slots)
        blocks = self.push_batch(batch)
        return blocks[0] if blocks else None

    def push_batch(self, revs: RevolutionBatch) -> list[AveragedBlock]:
        blocks = []
        i = 0
        while i < len(revs):
            take = min(self.n_revolutions - self._n, len(revs) - i)
            self._accumulate(revs, i, i + take)
            i += take
            if self._n == self.n_revolutions:
                blocks.append(self._finish(revs.slots))
        return blocks

    def _accumulate(self, revs: RevolutionBatch, a: int, b: int) -> None:
        c, s = revs.counts.shape[1:]
        if self._counts is None or self._counts.shape[1:] != (c, s):
            self._check_calibration(c)
            self._counts = np.empty((self.n_revolutions, c, s), np.int16)
            self._n = 0
        n0, n1 = self._n, self._n + (b - a)
        self._counts[n0:n1] = revs.counts[a:b]
        self._revs[n0:n1] = revs.rev[a:b]
        self._periods[n0:n1] = revs.period_s[a:b]
        self._n = n1

    def _check_calibration(self, c: int) -> None:
        for name, v in (("gains", self._gains), ("offsets", self._offsets)):
            if v is not None and v.shape != (c,):
                raise ValueError(f"{name} has {v.size} values for {c} channels")

    def _finish(self, slots: np.ndarray) -> AveragedBlock:
        n, c = self._n, self._counts.shape[1]
        gains = np.ones(c) if self._gains is None else self._gains
        offsets = np.zeros(c) if self._offsets is None else self._offsets
        theta = slots * (2 * np.pi / 360)
        counts = self._counts[:n]
        mean = counts.mean(axis=0) * gains[:, None] + offsets[:, None]
        fit = harmonic_fit(mean, theta)
        periods = self._periods[:n]
        known = periods[~np.isnan(periods)]
        speed = 2 * np.pi / known.mean() if len(known) else float("nan")
        block = AveragedBlock(
            orbit_speed=float(speed), theta=theta, mean=mean, phasors=fit.phasor,
            record_phasors=phasor(counts, theta) * gains, rms_residual=fit.rms_residual, dc=fit.mean,
            revs=self._revs[:n].copy(),
        )
        self._n = 0
        return block
