"""Non-synchronous disturbances and sensor noise, at the output of the chain.

Force channels: spindle unbalance and misalignment at the spin harmonics,
rolling-element bearing (ball-pass) orders of the spin, the narrow-band
response of a structural mode of the bearing housing, mains interference and
white noise. Probe channels: electrical runout of the probe tracks at the
spin harmonics (the y probe sits 90 degrees on), bearing orders, mains and
white noise. None of them is synchronous with the orbit, so time averaging
removes them; per revolution they set the coherence. Pure numpy, SI.
"""

from __future__ import annotations

import math

import numpy as np

from sim.config import NoiseConfig
from sim.streams import Purpose, SeedStreams

TWO_PI = 2.0 * math.pi
RESONANCE_LINES = 12  # sinusoids spanning the mode's half-power band a few times
#: simulated s between the points the resonance's slow complex envelope is evaluated at, then interpolated
#: (lines within +-9 Hz of the mode: the response off by 0.5 % of its rms at most; every 8th sample, as before,
#: was 16 ms apart at the paper point's ratio 0.65)
ENVELOPE_STEP_S = 4e-3
LOW_NODES = 1024  # grid points of the envelope's table of turns


def resonance_lines(f_n: float, zeta: float, rms: float) -> tuple[np.ndarray, np.ndarray]:
    """(frequencies Hz, amplitudes) of a narrow-band process shaped like a
    single-degree-of-freedom mode (f_n, zeta) with total rms ``rms``."""
    x = np.linspace(-3.0, 3.0, RESONANCE_LINES)
    f = f_n * (1.0 + zeta * x)
    r = f / f_n
    w = 1.0 / np.sqrt((1 - r * r) ** 2 + (2 * zeta * r) ** 2)
    return f, rms * math.sqrt(2.0) * w / math.sqrt(float(np.sum(w * w)))


class Disturbances:
    """Disturbances of the channels; random phases fixed per channel at construction (drawn from
    ``rng``), white noise per slot edge from ``streams`` (keyed by the global slot index)."""

    def __init__(self, noise: NoiseConfig, channels, white: np.ndarray, rng: np.random.Generator, streams: SeedStreams):
        self.nz = noise
        self.channels = channels
        self.white = white
        self.streams = streams
        n = len(channels)
        self._line = rng.uniform(0, TWO_PI, n)
        self._orders = rng.uniform(0, TWO_PI, (n, len(noise.bearing_orders)))
        self._spin = rng.uniform(0, TWO_PI, (n, len(noise.spin_force)))
        self._runout = rng.uniform(0, TWO_PI, (2, len(noise.runout)))  # per probe plane
        self._res_f, self._res_a = resonance_lines(
            noise.resonance_frequency, noise.resonance_damping, noise.resonance_force
        )
        self._res_phase = rng.uniform(0, TWO_PI, (n, RESONANCE_LINES))
        # the envelope's lines at grid point m = hi * LOW_NODES + lo: a table of the low part's turns
        # times the high part's (few per call), weighted by each channel's amplitudes and phases
        self._res_turn = TWO_PI * (self._res_f - noise.resonance_frequency) * ENVELOPE_STEP_S  # rad per grid step
        self._res_low = np.exp(1j * np.outer(np.arange(LOW_NODES), self._res_turn))
        self._res_weight = self._res_a * np.exp(1j * self._res_phase)  # (channels, lines)

    def add(self, k: int, val: np.ndarray, t: np.ndarray, spin_angle: np.ndarray, g: np.ndarray) -> np.ndarray:
        """``val`` of channel k plus its disturbances at times t (s), spin angles (rad) and global
        slot indices g."""
        nz, ch = self.nz, self.channels[k]
        force = ch.kind == "force"
        orders = nz.bearing_force if force else nz.bearing_probe
        for o, ph in zip(nz.bearing_orders, self._orders[k]):
            val = val + orders * np.sin(o * spin_angle + ph)
        val = val + (nz.line_force if force else nz.line_probe) * np.sin(TWO_PI * nz.line_frequency * t + self._line[k])
        if force:
            for h, (amp, ph) in enumerate(zip(nz.spin_force, self._spin[k]), start=1):
                val = val + amp * np.sin(h * spin_angle + ph)
            if nz.resonance_force:
                val = val + self._resonance(k, np.asarray(t, dtype=float))
        else:
            plane = 0 if ch.plane > 0 else 1
            shift = 0.0 if ch.axis == 0 else -math.pi / 2  # y probe sits 90 deg on
            for h, (amp, ph) in enumerate(zip(nz.runout, self._runout[plane]), start=1):
                val = val + amp * np.cos(h * (spin_angle + shift) + ph)
        if self.white[k]:
            val = val + self.white[k] * self.streams.slot_normals(Purpose.WHITE, k, g)
        return val

    def _resonance(self, k: int, t: np.ndarray) -> np.ndarray:
        """The mode's narrow-band response, Re(z(t) e^{i 2 pi f_n t}): its slowly varying
        envelope z (lines f_j - f_n, a few Hz) is evaluated on the simulated-time grid of
        ENVELOPE_STEP_S (only at the grid points next to a sample: a slow orbit's sparse samples cost no
        more than their number) and interpolated linearly, so a sample's value depends on its time alone."""
        if not t.size:
            return np.zeros(0)
        at = t / ENVELOPE_STEP_S
        below = np.floor(at)
        step = below.astype(np.int64)
        # the grid points around a sample: two sorted runs when t increases, merged by timsort in linear time
        ends = np.sort(np.concatenate([step, step + 1]), kind="stable")
        nodes = ends[np.r_[True, np.diff(ends) > 0]]
        high, which = np.unique(nodes // LOW_NODES, return_inverse=True)
        turns = self._res_low[nodes % LOW_NODES] * np.exp(1j * np.outer(high * float(LOW_NODES), self._res_turn))[which]
        env = turns @ self._res_weight[k]
        j = np.searchsorted(nodes, step)  # nodes[j] = below, nodes[j + 1] = below + 1
        z = env[j] + (env[j + 1] - env[j]) * (at - below)
        zr, zi = z.real, z.imag
        carrier = TWO_PI * self.nz.resonance_frequency * t
        return zr * np.sin(carrier) + zi * np.cos(carrier)
