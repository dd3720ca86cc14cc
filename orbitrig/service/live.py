"""What a person watching a run needs, built from the run's engine (spec: the
``<prefix>/live`` topic and the ``step``/``settings`` of a ``waiting`` status).

:class:`LiveFeed` listens to one :class:`orbitrig.run.engine.RunEngine`: it keeps
the running mean of the revolutions of the block being measured (the latest
averaged revolution, SI = gain * counts + offset) and, at most ``rate_hz``
times a second while the run lives, publishes

``{"run_id", "point", "frequency", "direction", "revolutions", "orbit_hz",
"spin_rpm", "drives", "aux", "waveforms", "units", "bands"}``

- ``drives``: both drives as :meth:`drives.state.RigDriveState.to_dict` (rpm and
  percent: for people);
- ``aux``: the CAN sensor values in SI (K, Pa, m^3/s, -), their units in ``units``;
- ``waveforms``: one averaged revolution per channel, SI (N, m), samples in slot order;
- ``bands``: interlock and verification bands ``{name: [low, high]}`` in SI
  (an addition to the spec's field list: the page draws them);
- ``settings_measured`` (while the run waits for a manual setting): the settings as
  measured now, SI, as in the waiting status (an addition: the page's manual panel
  follows them live).

While the run waits for an operator, :meth:`LiveFeed.waiting_fields` gives the
status fields ``step`` and ``settings`` = ``{name: {"value", "unit", "measured", "band"}}``
(asked and measured manual settings, SI; ``measured`` null when not measured now; ``band``
[low, high] accepted by the run's verification, orbitrig.run.verification.setting_bands).

Nothing old passes for now: ``orbit_hz`` and the measured orbit radius and static
eccentricity come only from current revolutions (the latest no older than FRESH_PERIODS
orbit periods or FRESH_WALL_S wall s, the longer, the orbit drive still at the setpoint it
had then; the geometry only from revolutions that came after the present wait began), else
null. The bands are the point being set up or run (the latest waited for, else the progress's).
"""

from __future__ import annotations

import asyncio
import logging
import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from orbitrig.service import protocol as proto
from orbitrig.config import MPA, RPM
from orbitrig.run.engine import ProgressEvent, RunEngine
from orbitrig.run.plan import Plan
from orbitrig.run.steps import SetManual
from orbitrig.run.states import RunState
from orbitrig.run.verification import setting_bands
from reduction.whirl import Whirl
from rigunits import ONE

log = logging.getLogger(__name__)

#: CAN sensor values of the live payload and their SI units.
AUX_UNITS = {
    "t_recess": "K",
    "t_groove": "K",
    "t_supply": "K",
    "flow": "m^3/s",
    "p_supply": "Pa",
    "p_recess_1": "Pa",
    "p_recess_2": "Pa",
    "p_recess_3": "Pa",
    "p_recess_4": "Pa",
    "beta": ONE,
}
#: The manual settings of an operating point and their SI units.
SETTING_UNITS = {"orbit_radius": "m", "static_eccentricity": ONE, "recess_pressure": "Pa", "pressure_ratio": ONE}
LIVE_STATES = (RunState.RUNNING, RunState.PAUSED, RunState.WAITING, RunState.STOPPING)
#: Revolutions are current while the latest is at most this many orbit periods old ...
FRESH_PERIODS = 3.0
#: ... or this many wall s, the longer (the ADC link delivers revolutions in batches).
FRESH_WALL_S = 1.0


class RevolutionAverage:
    """Running mean of the revolutions of one block, in engineering units (SI)."""

    def __init__(self, gains: list[float], offsets: list[float]):
        self._gain = np.asarray(gains, dtype=float)[:, None]
        self._offset = np.asarray(offsets, dtype=float)[:, None]
        self._sum: np.ndarray | None = None
        self.count = 0
        self.slots: np.ndarray | None = None  # (C, S) slot of each sample
        self.period_s: float | None = None  # orbit period of the latest revolution

    def reset(self) -> None:
        self._sum, self.count, self.period_s = None, 0, None

    def add(self, counts: np.ndarray, slots: np.ndarray, period_s: float | None) -> None:
        c = np.asarray(counts, dtype=float)
        if self._sum is None or self._sum.shape != c.shape:
            self._sum, self.count = np.zeros_like(c), 0
        self._sum += c
        self.count += 1
        self.slots = np.asarray(slots)
        if period_s is not None and period_s > 0:
            self.period_s = period_s

    def mean(self) -> np.ndarray | None:
        """(C, S) SI values of the averaged revolution, None before the first."""
        if self._sum is None or self.count == 0:
            return None
        return self._gain * (self._sum / self.count) + self._offset


class LiveFeed:
    """The live view of one run; see the module docstring."""

    def __init__(self, engine: RunEngine, plan: Plan, send: Callable[[bytes], None], *, rate_hz: float = 5.0):
        self.engine = engine
        self.rig = engine.rig
        self._send = send
        self.interval = 1.0 / rate_hz
        self.average = RevolutionAverage(self.rig.gains, self.rig.offsets)
        self._manual = {s.point: s for s in plan.steps if isinstance(s, SetManual) and s.point is not None}
        self._block: tuple[int, int] = (0, 0)
        self._point = self._frequency = self._revolutions = 0
        self._revs = 0  # revolutions seen in all
        self._rev_at: float | None = None  # time.monotonic() of the latest revolution
        self._rev_ref: float | None = None  # the orbit drive's setpoint (rad/s) then
        self._wait: tuple[str, int] | None = None  # the present wait: step id, revolutions seen before it
        self._waited_point: int | None = None  # the point of the latest wait
        self.sent = 0
        engine.subscribe(self._on_event)
        engine.revolution_taps.append(self._on_revolution)

    # -- engine events -------------------------------------------------------------

    def _on_event(self, event: Any) -> None:
        if isinstance(event, ProgressEvent):
            block = (event.point, event.frequency)
            if block != self._block:
                self._block = block
                self.average.reset()  # a new block: its own average
            self._point, self._frequency, self._revolutions = event.point, event.frequency, event.revolutions
        self._note_wait()

    def _on_revolution(self, rev: Any) -> None:
        self.average.add(rev.counts, rev.slots, rev.period_s)
        orbit = self._orbit_drive()
        self._revs, self._rev_at = self._revs + 1, time.monotonic()
        self._rev_ref = None if orbit is None else orbit.reference

    def _note_wait(self) -> tuple[str, int] | None:
        """The present wait (its step id, the revolutions seen before it began), else None."""
        step = self.engine.waiting_step if self.engine.state == RunState.WAITING else None
        if step is None:
            self._wait = None
        elif self._wait is None or self._wait[0] != step:
            self._wait = (step, self._revs)
            self._waited_point = _step_point(step)
        return self._wait

    def _orbit_drive(self) -> Any:
        io = self.engine.io
        return None if io is None or io.drives is None else io.drives.state.orbit

    def _current(self) -> bool:
        """Are the averaged revolutions current: the latest recent (FRESH_PERIODS, FRESH_WALL_S),
        the orbit drive turning at the setpoint it had then?"""
        orbit, at = self._orbit_drive(), self._rev_at
        if self.average.count == 0 or at is None or orbit is None or orbit.stopped or orbit.reference != self._rev_ref:
            return False
        fresh = self.engine.access.time_scale.wall(FRESH_PERIODS * (self.average.period_s or 0.0))
        return time.monotonic() - at <= max(fresh, FRESH_WALL_S)

    # -- publishing ------------------------------------------------------------------

    async def run(self, run_task: asyncio.Task) -> None:
        """Publish every ``interval`` s while ``run_task`` lives; never raises."""
        while not run_task.done():
            try:
                payload = self.payload()
                if payload is not None:
                    self._send(proto.dumps(payload))
                    self.sent += 1
            except Exception:  # the live view must never disturb the run
                log.exception("live payload failed")
            await asyncio.sleep(self.interval)

    def payload(self) -> dict[str, Any] | None:
        """The live payload now; None while the rig is not open or the run not active."""
        io = self.engine.io
        if io is None or io.drives is None or self.engine.state not in LIVE_STATES:
            return None
        drives = io.drives.state
        orbit, spin = drives.orbit, drives.spin
        names = [c.name for c in sorted(self.rig.channels, key=lambda c: c.index)]
        mean = self.average.mean()
        period = self.average.period_s if self._current() else None
        return {
            "run_id": self.engine.run_id,
            "point": self._point,
            "frequency": self._frequency,
            "direction": _direction(orbit),
            "revolutions": self._revolutions,
            "orbit_hz": 1.0 / period if period else None,
            "spin_rpm": None if spin is None else spin.actual / RPM,
            "drives": drives.to_dict(),
            "aux": self._aux(io),
            "waveforms": {} if mean is None else {n: mean[i] for i, n in enumerate(names)},
            "units": {**{c.name: c.unit for c in self.rig.channels}, **AUX_UNITS},
            "bands": self._bands(),
            **({"settings_measured": self._settings_measured()} if self.engine.state == RunState.WAITING else {}),
        }

    @staticmethod
    def _aux(io: Any) -> dict[str, float | bool | None]:
        a = io.aux.latest() if io.aux is not None else None
        if a is None:
            return {}
        out: dict[str, Any] = {
            "t_recess": a.t_recess,
            "t_groove": a.t_groove,
            "t_supply": a.t_supply,
            "flow": a.flow,
            "p_supply": a.p_supply,
            "beta": a.beta,
        }
        out.update({f"p_recess_{i + 1}": v for i, v in enumerate(a.p_recess)})
        out.update(sensor_fault=a.sensor_fault, pump_off=a.pump_off, node_lost=a.node_lost)
        return out

    def _bands(self) -> dict[str, list[float]]:
        lim = self.rig.interlocks
        bands: dict[str, list[float]] = {}
        if lim.check_supply_pressure:
            bands["p_supply"] = [lim.supply_pressure_min_mpa * MPA, lim.supply_pressure_max_mpa * MPA]
        step = self._manual_step()
        if step is not None:
            accepted = setting_bands(step, self.rig.verify)
            bands["p_recess"], bands["beta"] = accepted["recess_pressure"], accepted["pressure_ratio"]
        return bands

    def _manual_step(self) -> SetManual | None:
        point = self._manual_point()
        return None if point is None else self._manual.get(point)

    def _manual_point(self) -> int | None:
        """Index of the operating point being set up or run: the waiting step's, else the later
        of the latest waited for and the progress's (which moves on at the point's first block)."""
        if self._note_wait() is not None:
            return self._waited_point
        points = sorted(self._manual)
        progress = points[self._point - 1] if 0 < self._point <= len(points) else None
        return max((p for p in (progress, self._waited_point) if p is not None), default=None)

    # -- waiting status ----------------------------------------------------------------

    def waiting_fields(self, state: str) -> dict[str, Any] | None:
        """``{"step", "settings"}`` for a ``waiting`` status, else None."""
        step_id = self.engine.waiting_step
        if state != RunState.WAITING or not step_id:
            return None
        step = self._manual_step()
        if step is None:
            return {"step": step_id, "settings": {}}
        measured, bands = self._measured(), setting_bands(step, self.rig.verify)
        asked = {
            "orbit_radius": step.orbit_radius,
            "static_eccentricity": step.static_eccentricity,
            "recess_pressure": step.recess_pressure,
            "pressure_ratio": step.pressure_ratio,
        }
        return {
            "step": step_id,
            "settings": {
                k: {"value": v, "unit": SETTING_UNITS[k], "measured": measured.get(k), "band": bands[k]}
                for k, v in asked.items()
            },
        }

    def _settings_measured(self) -> dict[str, float | None]:
        """Every manual setting as measured now, null when not (the page then clears an old value)."""
        measured = self._measured()
        return {k: measured.get(k) for k in SETTING_UNITS}

    def _measured(self) -> dict[str, float]:
        """Manual settings as measured now: pressures from CAN, orbit radius and static
        eccentricity from the averaged revolution of the displacement probes when it is
        current and came after the present wait began (the run acquires none while waiting)."""
        out: dict[str, float] = {}
        io = self.engine.io
        a = io.aux.latest() if io is not None and io.aux is not None else None
        if a is not None and not a.node_lost:
            out["recess_pressure"] = float(np.mean(a.p_recess))
            out["pressure_ratio"] = float(a.beta)
        mean, slots, wait = self.average.mean(), self.average.slots, self._note_wait()
        if mean is not None and slots is not None and wait is not None and self._revs > wait[1] and self._current():
            out.update(_geometry(mean, slots, self.rig.channel_index, self.rig.bearing.clearance))
        return {k: v for k, v in out.items() if math.isfinite(v)}


def _geometry(mean: np.ndarray, slots: np.ndarray, ch: dict[str, int], clearance: float) -> dict[str, float]:
    """Orbit radius (m) and static eccentricity (-) of one averaged revolution: the
    first harmonic and the mean of x and y (mean of probe planes A and B)."""
    from daq.frames import slot_angle
    from reduction.errors import ReductionError
    from reduction.fourier import harmonic_fit

    try:
        fit = harmonic_fit(mean, slot_angle(slots), axis=-1)
    except ReductionError:
        return {}
    x = (fit.phasor[ch["x_a"]] + fit.phasor[ch["x_b"]]) / 2
    y = (fit.phasor[ch["y_a"]] + fit.phasor[ch["y_b"]]) / 2
    x0 = (fit.mean[ch["x_a"]] + fit.mean[ch["x_b"]]) / 2
    y0 = (fit.mean[ch["y_a"]] + fit.mean[ch["y_b"]]) / 2
    return {"orbit_radius": float((abs(x) + abs(y)) / 2), "static_eccentricity": float(math.hypot(x0, y0) / clearance)}


def _step_point(step: str) -> int | None:
    """The point index of a waiting step's id ('manual:0001' -> 1), else None."""
    try:
        return int(step.split(":", 1)[1])
    except (IndexError, ValueError):
        return None


def _direction(orbit: Any) -> str | None:
    """Whirl direction of the orbit drive: the sign of its reference, else of its actual speed."""
    speed = 0.0 if orbit is None else (orbit.reference or orbit.actual)
    return None if speed == 0 else Whirl.of(speed)


def attach(engine: Any, plan: Any, send: Callable[[bytes], None]) -> LiveFeed | None:
    """A LiveFeed on ``engine`` when it is the rig's RunEngine (else None: a test double)."""
    if not isinstance(engine, RunEngine) or not isinstance(plan, Plan):
        return None
    return LiveFeed(engine, plan, send)
