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

TWO_PI = 2.0 * math.pi
RESONANCE_LINES = 12  # sinusoids spanning the mode's half-power band a few times
ENVELOPE_STEP = 8  # the resonance's slow complex envelope is evaluated every 8th sample, then interpolated


def resonance_lines(f_n: float, zeta: float, rms: float) -> tuple[np.ndarray, np.ndarray]:
    """(frequencies Hz, amplitudes) of a narrow-band process shaped like a
    single-degree-of-freedom mode (f_n, zeta) with total rms ``rms``."""
    x = np.linspace(-3.0, 3.0, RESONANCE_LINES)
    f = f_n * (1.0 + zeta * x)
    r = f / f_n
    w = 1.0 / np.sqrt((1 - r * r) ** 2 + (2 * zeta * r) ** 2)
    return f, rms * math.sqrt(2.0) * w / math.sqrt(float(np.sum(w * w)))


class Disturbances:
    """Disturbances of the channels; random phases fixed per channel at construction."""

    def __init__(self, noise: NoiseConfig, channels, white: np.ndarray, rng: np.random.Generator):
        self.nz = noise
        self.channels = channels
        self.white = white
        self.rng = rng
        n = len(channels)
        self._line = rng.uniform(0, TWO_PI, n)
        self._orders = rng.uniform(0, TWO_PI, (n, len(noise.bearing_orders)))
        self._spin = rng.uniform(0, TWO_PI, (n, len(noise.spin_force)))
        self._runout = rng.uniform(0, TWO_PI, (2, len(noise.runout)))  # per probe plane
        self._res_f, self._res_a = resonance_lines(
            noise.resonance_frequency, noise.resonance_damping, noise.resonance_force
        )
        self._res_phase = rng.uniform(0, TWO_PI, (n, RESONANCE_LINES))

    def add(self, k: int, val: np.ndarray, t: np.ndarray, spin_angle: np.ndarray) -> np.ndarray:
        """``val`` of channel k plus its disturbances at times t (s) and spin angles (rad)."""
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
            val = val + self.rng.normal(0.0, self.white[k], np.shape(val))
        return val

    def _resonance(self, k: int, t: np.ndarray) -> np.ndarray:
        """The mode's narrow-band response, Re(z(t) e^{i 2 pi f_n t}): its slowly varying
        envelope z (lines f_j - f_n, a few Hz) is evaluated every ENVELOPE_STEP samples and
        interpolated linearly (exact where t is not increasing)."""
        nz = self.nz
        df = self._res_f - nz.resonance_frequency
        n = t.size
        coarse = n > 4 * ENVELOPE_STEP and t[-1] > t[0]
        tc = np.r_[t[::ENVELOPE_STEP], t[-1]] if coarse else t
        arg = TWO_PI * np.multiply.outer(tc, df) + self._res_phase[k]
        zr, zi = np.cos(arg) @ self._res_a, np.sin(arg) @ self._res_a
        if coarse and np.all(np.diff(tc) > 0):
            zr, zi = np.interp(t, tc, zr), np.interp(t, tc, zi)
        elif coarse:  # not increasing: evaluate exactly
            arg = TWO_PI * np.multiply.outer(t, df) + self._res_phase[k]
            zr, zi = np.cos(arg) @ self._res_a, np.sin(arg) @ self._res_a
        carrier = TWO_PI * nz.resonance_frequency * t
        return zr * np.sin(carrier) + zi * np.cos(carrier)
