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
LOW_BITS = 10
LOW_NODES = 1 << LOW_BITS  # grid points of the envelope's table of turns, and of each of its tables
ENVELOPE_TABLES = 16  # envelope tables (LOW_NODES grid points, 4.1 s, of the force channels, 128 kB) a rig keeps
#: simulated s of one envelope table (LOW_NODES grid points of ENVELOPE_STEP_S)
TABLE_S = LOW_NODES * ENVELOPE_STEP_S
#: a conversion with fewer samples than this per TABLE_S of the time its samples span evaluates the envelope
#: at its grid points alone (Disturbances._envelope_at: the table's bits), not by tables: a slow orbit's
#: handful of samples per 4.1 s (3 a force channel at a 1 rpm orbit, 31 at 10 rpm) made a table of 1024
#: points each. A live board's tick of a few samples in 0.01 s is dense: it takes the tables cached for
#: the ticks before it (16 µs a call against 65 to 90 µs summing the lines at its grid points)
SPARSE_SAMPLES = 128


def tabulated(samples: int, span: float) -> bool:
    """Whether a channel's `samples` conversions whose times span `span` s take the resonance's envelope
    from tables (SPARSE_SAMPLES per TABLE_S at least; one sample alone does), else at their grid points
    alone."""
    return samples * TABLE_S >= SPARSE_SAMPLES * span


def resonance_lines(f_n: float, zeta: float, rms: float) -> tuple[np.ndarray, np.ndarray]:
    """(frequencies Hz, amplitudes) of a narrow-band process shaped like a
    single-degree-of-freedom mode (f_n, zeta) with total rms ``rms``."""
    x = np.linspace(-3.0, 3.0, RESONANCE_LINES)
    f = f_n * (1.0 + zeta * x)
    r = f / f_n
    w = 1.0 / np.sqrt((1 - r * r) ** 2 + (2 * zeta * r) ** 2)
    return f, rms * math.sqrt(2.0) * w / math.sqrt(float(np.sum(w * w)))


def _add_wave(val: np.ndarray, term: np.ndarray, phase: float, amp: float, wave=np.sin) -> None:
    """val += amp wave(term + phase), term (the argument, s or rad) overwritten: no temporary array."""
    term += phase
    wave(term, out=term)
    term *= amp
    val += term


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
        # the envelope's lines at grid point m = hi * LOW_NODES + lo: each channel's amplitudes and phases
        # turned to the table's first grid point hi * LOW_NODES, times the turns of lo (Disturbances._envelope)
        self._res_turn = TWO_PI * (self._res_f - noise.resonance_frequency) * ENVELOPE_STEP_S  # rad per grid step
        self._res_lines = np.exp(1j * np.outer(self._res_turn, np.arange(LOW_NODES)))  # (lines, LOW_NODES)
        self._res_weight = self._res_a * np.exp(1j * self._res_phase)  # (channels, lines)
        self._res_rows = {k: i for i, k in enumerate(i for i, c in enumerate(channels) if c.kind == "force")}
        self._envelopes: dict[int, np.ndarray] = {}  # table: the force channels' envelopes (Disturbances._envelope)

    def add(self, k: int, val: np.ndarray, t: np.ndarray, spin_angle: np.ndarray, g: np.ndarray) -> np.ndarray:
        """``val`` (float, changed in place and returned) of channel k plus its disturbances at times
        t (s), spin angles (rad) and global slot indices g."""
        nz, ch = self.nz, self.channels[k]
        force = ch.kind == "force"
        term = np.empty_like(val)  # the argument of each wave, then the wave (one buffer, in place)
        orders = nz.bearing_force if force else nz.bearing_probe
        for o, ph in zip(nz.bearing_orders, self._orders[k]):
            _add_wave(val, np.multiply(o, spin_angle, out=term), ph, orders)
        line = np.multiply(TWO_PI * nz.line_frequency, t, out=term)
        _add_wave(val, line, self._line[k], nz.line_force if force else nz.line_probe)
        if force:
            for h, (amp, ph) in enumerate(zip(nz.spin_force, self._spin[k]), start=1):
                _add_wave(val, np.multiply(h, spin_angle, out=term), ph, amp)
            if nz.resonance_force:
                val += self._resonance(k, np.asarray(t, dtype=float))
        else:
            plane = 0 if ch.plane > 0 else 1
            shift = 0.0 if ch.axis == 0 else -math.pi / 2  # y probe sits 90 deg on
            shifted = spin_angle + shift
            for h, (amp, ph) in enumerate(zip(nz.runout, self._runout[plane]), start=1):
                _add_wave(val, np.multiply(h, shifted, out=term), ph, amp, np.cos)
        if self.white[k]:
            normals = self.streams.slot_normals(Purpose.WHITE, k, g)
            normals *= self.white[k]
            val += normals
        return val

    def _envelope(self, high: int, k: int) -> np.ndarray:
        """Force channel k's resonance envelope at the grid points high * LOW_NODES + m, m < LOW_NODES:
        (Re, Im, Re and Im of the step to grid point m + 1), (4, LOW_NODES). The lines are summed one
        by one, in one order whatever the samples asked for; every force channel's table at once
        (cached per rig, the oldest dropped)."""
        tables = self._envelopes.get(high)
        if tables is None:
            ends = np.exp(1j * np.outer(self._res_turn, np.array([high, high + 1]) * float(LOW_NODES)))
            weight = self._res_weight[list(self._res_rows)]  # (force channels, lines)
            first, after = weight * ends[:, 0], weight * ends[:, 1]  # at the table's first grid point, the next's
            env = np.zeros((len(weight), LOW_NODES + 1), dtype=complex)
            for j in range(RESONANCE_LINES):
                env[:, :-1] += first[:, j : j + 1] * self._res_lines[j]
                env[:, -1] += after[:, j]  # as the next table's first grid point sums it
            tables = np.stack([env.real[:, :-1], env.imag[:, :-1], np.diff(env.real), np.diff(env.imag)], axis=1)
            if len(self._envelopes) >= ENVELOPE_TABLES:
                del self._envelopes[next(iter(self._envelopes))]  # the oldest
            self._envelopes[high] = tables
        return tables[self._res_rows[k]]

    def _envelope_at(self, k: int, m: np.ndarray) -> tuple[tuple[np.ndarray, np.ndarray], ...]:
        """Force channel k's envelope at grid points m and its step to m + 1, ((Re, step Re), (Im, step
        Im)), each (m.size,): the lines summed at those grid points alone, in the tables' order and with
        their products, so the same bits as `_envelope`'s (a table's last step ends at the next table's
        first grid point, whose turn of 0 is 1 exactly)."""
        nodes = np.concatenate([m, m + 1])
        tables, which = np.unique(nodes >> LOW_BITS, return_inverse=True)
        turned = self._res_weight[k][:, None] * np.exp(1j * np.outer(self._res_turn, tables * float(LOW_NODES)))
        low = nodes & (LOW_NODES - 1)
        env = np.zeros(nodes.size, dtype=complex)
        for j in range(RESONANCE_LINES):
            env += turned[j, which] * self._res_lines[j, low]
        here, there = env[: m.size], env[m.size :]
        return (here.real.copy(), there.real - here.real), (here.imag.copy(), there.imag - here.imag)

    def _resonance(self, k: int, t: np.ndarray) -> np.ndarray:
        """The mode's narrow-band response, Re(z(t) e^{i 2 pi f_n t}): its slowly varying
        envelope z (lines f_j - f_n, a few Hz) is tabulated on the simulated-time grid of
        ENVELOPE_STEP_S (tables of LOW_NODES grid points, 4.1 s, made for the samples that fall in
        them) and interpolated linearly, so a sample's value depends on its time alone, bit for bit,
        whatever else is converted with it."""
        if not t.size:
            return np.zeros(0)
        at = t / ENVELOPE_STEP_S
        below = np.floor(at)
        at -= below  # the fraction of the grid step
        m = below.astype(np.int64)  # the grid point below
        high = m >> LOW_BITS
        first, last = int(high.min()), int(high.max())
        if not tabulated(t.size, float(t.max() - t.min())):
            ends = self._envelope_at(k, m)
        else:
            if last - first < 4 + t.size // 1024:  # samples in time order, a few per grid step: tables in a row
                tables, j = np.arange(first, last + 1), m - first * LOW_NODES
            else:
                tables, which = np.unique(high, return_inverse=True)
                j = which * LOW_NODES + (m & (LOW_NODES - 1))
            env = np.concatenate([self._envelope(int(h), k) for h in tables], axis=1)
            ends = ((env[0][j], env[2][j]), (env[1][j], env[3][j]))
        parts = []
        for z, dz in ends:  # z = env[j] + step[j] * fraction, Re and Im
            dz *= at
            z += dz
            parts.append(z)
        carrier = np.multiply(TWO_PI * self.nz.resonance_frequency, t)
        out = np.sin(carrier)
        out *= parts[0]
        np.cos(carrier, out=carrier)
        carrier *= parts[1]
        out += carrier
        return out
