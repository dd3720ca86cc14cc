"""The A/D board's stream of slot edges: the orbit spindle's angle integrated from the orbit
drive's actual speed (rad/s, linear between the drive's speed knots within a tick, sim.speed_trace,
so a long tick of a stalled simulator turns it as the drive did; times the speed ripple), every slot edge it
passes converted (sequential: channel s mod C; simultaneous: all channels) and quantised, and
whole frames sent to the device server; slots the board's FIFO cannot hold, or that nobody
reads, are lost as whole frames. Simulated time (the rig's SimClock, s).

The board never trails the drives by more than `lead` (simulated s, LEAD_S by default): after each
tick the clock is held at the tick's end + lead (SimClock.hold), so a simulator that cannot convert
as fast as its speed-up asks (a loaded host, a stalled loop) slows its simulated time; no slot is
skipped or converted twice. Ticks come often enough that, keeping up, the clock never reaches the hold.
"""

from __future__ import annotations

import asyncio
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from sim.adc_board import SLOTS, AdcBoard, channel_slots
from sim.adc_server import AdcServer
from sim.clock import SimClock
from sim.physics import RigPhysics
from sim.streams import Purpose

SLOT_ANGLE = 2.0 * math.pi / SLOTS
#: simulated s the rig's clock (the drives' time) may run ahead of the board's last converted slot edge
LEAD_S = 1.0

#: (times, spin, orbit) of the spindles from simulated t0 to t1 (s, rad/s; SimRig.shaft_profile)
Profile = Callable[[float, float], tuple[np.ndarray, np.ndarray, np.ndarray]]


@dataclass
class BoardLag:
    """How far the board's conversions trail the rig's clock (simulated s): at each tick, from the
    end of the tick before (its last conversions) to the clock once the tick's own conversions are
    done, just before its frames go: the most the drives' time was ahead of the A/D's (<= lead)."""

    last: float = 0.0
    longest: float = 0.0

    def note(self, lag: float) -> None:
        self.last = lag
        self.longest = max(self.longest, lag)


@dataclass(frozen=True)
class _Tick:
    """One tick's segments (arrays, one entry each; speeds linear within one): start time and
    length (simulated s), spin and orbit speed at both ends (rad/s), spin angle (rad) and slots
    passed at the start and slots passed at the end, speed ripple factor."""

    t0: np.ndarray
    dt: np.ndarray
    spin0: np.ndarray
    spin1: np.ndarray
    orbit0: np.ndarray
    orbit1: np.ndarray
    phi0: np.ndarray
    g0: np.ndarray
    g1: np.ndarray
    ripple: np.ndarray


class SlotStream:
    """The slot clock and the conversions of one rig's board; ``profile(t0, t1)`` gives the
    spindles' speeds between two simulated times (rad/s, orbit signed; `Profile`)."""

    def __init__(
        self,
        clock: SimClock,
        physics: RigPhysics,
        board: AdcBoard,
        adc_server: AdcServer,
        profile: Profile,
        max_slots: int,
        lead: float = LEAD_S,
    ):
        self.clock, self.physics, self.board, self.adc_server = clock, physics, board, adc_server
        self._profile = profile
        self._max_slots = max_slots
        if not lead > 0:
            raise ValueError(f"lead must be > 0 simulated s, got {lead!r}")
        self.lead = lead
        self._g_pos = float(
            self.physics.streams.generator(Purpose.START).uniform(0.0, SLOTS)
        )  # slots passed since start
        self._g_next = math.ceil(self._g_pos)  # next slot edge to convert
        self._pending_g0 = self._g_next
        self._pending_counts: np.ndarray | None = None
        self._pending_t: np.ndarray | None = None
        self._t_last = 0.0
        self._spin_last = 0.0
        self._orbit_last = 0.0
        self._spin_angle = 0.0
        self.lag = BoardLag()

    def start(self) -> None:
        """Count simulated time from now (the rig's start); the clock held `lead` ahead."""
        self._t_last = self.clock.now()
        self.clock.hold(self._t_last + self.lead)

    def tick_period(self, tick: float) -> float:
        """Wall s to the next tick: `tick`, shorter at a high speed-up, so that the clock runs half
        the lead between two ticks (a tick in time, its conversions done, finds it short of the hold)."""
        return min(tick, 0.5 * self.lead / self.clock.speedup)

    @property
    def last_speeds(self) -> tuple[float, float]:
        """(spin, orbit) in rad/s at the last tick."""
        return self._spin_last, self._orbit_last

    async def step(self) -> None:
        """Advance the drives and spindles to now (at most the lead past the last tick); stream the
        completed frames (numerics in a thread); hold the clock the lead past this tick's end."""
        t_before = self._t_last
        try:
            await self._step()
        finally:
            self.lag.note(self.clock.now() - t_before)
            self.clock.hold(self._t_last + self.lead)

    async def _step(self) -> None:
        tick = self._advance_spindles()
        if tick is None:
            return
        g_end = math.floor(self._g_pos) + 1  # slot edges g_next .. g_end - 1 have passed
        if g_end <= self._g_next:
            return
        board = self.board
        if g_end - self._g_next > self._max_slots:  # the board's FIFO overflowed
            self._lose_pending(board.boundary_before(g_end - self._max_slots))
            self._g_next = max(self._g_next, self._pending_g0)
        b = board.boundary_before(g_end)  # frames before b are complete
        if b > self._pending_g0 and not self.adc_server.wants_data():
            self._lose_pending(b)  # nobody can take them: skip the numerics
        lo = max(self._g_next, self._pending_g0)
        if g_end > lo:
            g = np.arange(lo, g_end)
            t, spin_angle, orbit_inst, spin, orbit = self._interpolate(g, tick)
            counts = await asyncio.to_thread(self.convert, g, t, spin_angle, orbit_inst, spin, orbit)
            if self._pending_counts is None or not len(self._pending_counts):
                self._pending_counts, self._pending_t = counts, t
            else:
                self._pending_counts = np.concatenate([self._pending_counts, counts])
                self._pending_t = np.concatenate([self._pending_t, t])
        self._g_next = g_end
        if b > self._pending_g0:
            n, pending, pending_t = b - self._pending_g0, self._pending_counts, self._pending_t
            assert pending is not None and pending_t is not None  # b > pending_g0 implies g_end > lo: set above
            self.adc_server.send(board.encode(self._pending_g0, pending[:n], pending_t[:n]))
            self._pending_counts, self._pending_t = pending[n:], pending_t[n:]
            self._pending_g0 = b

    def _advance_spindles(self) -> _Tick | None:
        """Integrate both spindles from the last tick to now (the drives' speeds linear between
        their knots, times the speed ripple at each segment's middle). Returns the tick's
        segments, or None when no simulated time has passed."""
        now = self.clock.now()
        if now <= self._t_last:
            return None
        times, spin, orbit = self._profile(self._t_last, now)
        t0, dt = times[:-1], np.diff(times)
        ripple = np.asarray(self.physics.ripple(t0 + 0.5 * dt), dtype=float)
        g_step = 0.5 * (np.abs(orbit[:-1]) + np.abs(orbit[1:])) * ripple * dt / SLOT_ANGLE
        phi_step = 0.5 * (spin[:-1] + spin[1:]) * ripple * dt  # unwrapped: ball-pass orders
        g = self._g_pos + np.concatenate([[0.0], np.cumsum(g_step)])
        phi = self._spin_angle + np.concatenate([[0.0], np.cumsum(phi_step)])
        tick = _Tick(t0, dt, spin[:-1], spin[1:], orbit[:-1], orbit[1:], phi[:-1], g[:-1], g[1:], ripple)
        self._g_pos, self._spin_angle = float(g[-1]), float(phi[-1])
        self._t_last, self._spin_last, self._orbit_last = now, float(spin[-1]), float(orbit[-1])
        return tick

    def _interpolate(self, g: np.ndarray, tick: _Tick):
        """Time, spin angle and orbit speed at the slot edges g inside a tick; the tick's
        operating point (spin, orbit: its end's, the orbit's before it if it ends at rest)."""
        k = np.minimum(np.searchsorted(tick.g1, g, side="right"), len(tick.dt) - 1)
        span = tick.g1[k] - tick.g0[k]
        frac = np.divide(g - tick.g0[k], span, out=np.zeros(len(g)), where=span > 0)
        tau, dt, spin0 = frac * tick.dt[k], tick.dt[k], tick.spin0[k]
        spin_angle = tick.phi0[k] + (spin0 * tau + (tick.spin1[k] - spin0) * tau * tau / (2 * dt)) * tick.ripple[k]
        orbit_inst = tick.orbit0[k] + (tick.orbit1[k] - tick.orbit0[k]) * frac
        spin, orbit, orbit_before = float(tick.spin1[-1]), float(tick.orbit1[-1]), float(tick.orbit0[0])
        return tick.t0[k] + tau, spin_angle, orbit_inst, spin, (orbit if orbit != 0 else orbit_before)

    def _lose_pending(self, upto: int) -> None:
        """The board lost the slots from the pending ones up to ``upto`` (a frame boundary)."""
        if upto <= self._pending_g0:
            return
        self.board.lose(self._pending_g0, upto)
        if self._pending_counts is not None and self._pending_t is not None:  # set together
            n = upto - self._pending_g0
            self._pending_counts, self._pending_t = self._pending_counts[n:], self._pending_t[n:]
        self._pending_g0 = upto

    def convert(self, g, t, spin_angle, orbit_inst, spin, orbit) -> np.ndarray:
        """Counts of the conversions at global slots g (sequential (n,), simultaneous (n, C))."""
        ph, board = self.physics, self.board
        C = board.channels
        theta = (g % SLOTS) * SLOT_ANGLE
        if board.simultaneous:
            vals: np.ndarray = np.empty((len(g), C))
            for k in range(C):
                vals[:, k] = ph.channel_values(k, theta, t, spin_angle, orbit_inst, spin, orbit, g)
            return board.quantize(vals)
        vals = np.empty(len(g))
        for k, sl in enumerate(channel_slots(C, "sequential", int(g[0]))):
            vals[sl] = ph.channel_values(k, theta[sl], t[sl], spin_angle[sl], orbit_inst[sl], spin, orbit, g[sl])
        return board.quantize(vals, board.channel_of_slot(g))
