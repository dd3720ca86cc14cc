"""The measurement chain: what each channel does to the signal it measures.

Per channel, a complex frequency response applied to every harmonic of the
orbit-periodic signal (f in Hz, time frequency):
    H(f) = (1 + gain error) * B(f) * exp(-i 2 pi f tau) * exp(-i lag)
B the 2nd-order Butterworth anti-alias filter with corner f_c,
B(f) = 1 / (1 + sqrt(2) (i f/f_c) + (i f/f_c)^2); tau the force-to-probe delay
(force channels) or the probe's own delay (probe channels, ``probe_delay``); lag the constant phase error of the load measuring
system (force channels only). At f = 0 (the static part) only the gain acts.
Probe channels carry the common sensitivity error on top of their own gain
error. The non-synchronous disturbances are specified at the chain output.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sim.config import CHANNEL_NAMES, SimConfig


@dataclass(frozen=True)
class ChannelChain:
    """Calibration of one channel (SI: relative, Hz, s, rad)."""

    gain: float  # total relative gain error (channel, LMS or probe sensitivity included)
    cutoff: float  # Hz, 0 = no filter
    delay: float  # s, pure time delay
    lag: float  # rad, constant phase lag

    def response(self, f) -> np.ndarray:
        """H(f) for time frequencies f >= 0 (Hz); H(0) = 1 + gain."""
        f = np.asarray(f, dtype=float)
        h = np.full(f.shape, 1.0 + self.gain, dtype=complex)
        if self.cutoff > 0:
            s = 1j * f / self.cutoff
            h = h / (1.0 + math.sqrt(2.0) * s + s * s)
        lag = np.where(f > 0, self.lag, 0.0)
        return h * np.exp(-2j * math.pi * f * self.delay - 1j * lag)

    @property
    def group_delay(self) -> float:
        """Low-frequency delay of filter and delay together, s (Butterworth: sqrt(2) / (2 pi f_c))."""
        filt = math.sqrt(2.0) / (2 * math.pi * self.cutoff) if self.cutoff > 0 else 0.0
        return self.delay + filt


IDEAL = ChannelChain(gain=0.0, cutoff=0.0, delay=0.0, lag=0.0)


def channel_chains(cfg: SimConfig) -> dict[str, ChannelChain]:
    """The chain of every channel name (ideal where the chain is disabled; the
    load measuring systems' gain and phase errors always act, as before)."""
    ch, lms = cfg.chain, cfg.lms
    out = {}
    for i, name in enumerate(CHANNEL_NAMES):
        gain, cutoff, delay, lag = 0.0, 0.0, 0.0, 0.0
        if ch.enabled:
            gain, cutoff = ch.gain_error[i], ch.filter_cutoff[i]
        if name.startswith("f"):
            piezo = name.endswith("piezo")
            g_lms = lms.piezo_gain_error if piezo else lms.strain_gain_error
            lag = lms.piezo_phase_lag if piezo else lms.strain_phase_lag
            gain = (1 + gain) * (1 + g_lms) - 1
            delay = ch.force_delay if ch.enabled else 0.0
        elif ch.enabled:
            gain = (1 + gain) * (1 + ch.probe_sensitivity_error) - 1
            delay = ch.probe_delay_of(name)
        out[name] = ChannelChain(gain=gain, cutoff=cutoff, delay=delay, lag=lag)
    return out


def calibration_errors(cfg: SimConfig) -> dict:
    """The calibration errors the scenario injects, for checking a type-B budget.

    {"channels": {name: {"gain", "phase", "delay", "cutoff"}}, "sensitivity": s,
     "x"/"y"/"fx"/"fy": {"gain", "phase", "delay"}}: gain relative (for probes
    without the common sensitivity error s), phase the constant lag (rad),
    delay the low-frequency delay of filter and time delay (s); x, y the mean
    of the two probe planes, fx, fy the piezoelectric system."""
    chains = channel_chains(cfg)
    s = cfg.chain.probe_sensitivity_error if cfg.chain.enabled else 0.0
    per = {}
    for name, c in chains.items():
        gain = (1 + c.gain) / (1 + s) - 1 if not name.startswith("f") else c.gain
        per[name] = {"gain": gain, "phase": c.lag, "delay": c.group_delay, "cutoff": c.cutoff}

    def mean(a: str, b: str) -> dict:
        return {k: (per[a][k] + per[b][k]) / 2 for k in ("gain", "phase", "delay")}

    return {
        "channels": per,
        "sensitivity": s,
        "x": mean("x_a", "x_b"),
        "y": mean("y_a", "y_b"),
        "fx": {k: per["fx_piezo"][k] for k in ("gain", "phase", "delay")},
        "fy": {k: per["fy_piezo"][k] for k in ("gain", "phase", "delay")},
    }
