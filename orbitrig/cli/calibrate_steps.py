"""The steps of `orbitrig calibrate` on the rig or the simulator, and the records they write.

Each step opens the rig (or starts the simulator) in a `CalibrationSession`, measures, and
returns a new complete `CalibrationRecord`: the active record (or, without one, rig.toml's
``[calibration_uncertainty]``) with what the step measured replaced.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import typer

from drives.errors import DriveLimitError
from drives.state import NOT_READ
from orbitrig.config import LMS, MPA, RPM, CalibrationRecord, CalibrationUncertainty, LoadGains
from orbitrig.config import ProbeRunout, RecordStep, Reference, RigConfig, Runout
from orbitrig.errors import OrbitrigError
from orbitrig.cli.calibrate_prompt import Unanswered, confirmed
from orbitrig.run.calibration import AsksOperator, CalibrationSession, SlowRoll, unrecordable
from orbitrig.run.calibration_checks import CalibrationFailed
from orbitrig.config import PROBE_CHANNELS as PROBES
from orbitrig.run.calibration_measure import (
    REMOVE_LOADS,
    REMOVE_REFERENCE,
    REMOVE_STEP,
    measure_delay,
    measure_loads,
    measure_probes,
    measure_runout,
    slip_refused,
)
from orbitrig.run.calibration_measure import fitted_delay, probe_delays
from orbitrig.run.drive_setup import drive_limits
from orbitrig.run.rig_io import RigAccess
from rigunits import UM, micrometres, now_iso, rpm_text
from reduction.calibration import expanded, fit_gain_matrix, fit_probe, static_loads

FORCE_CHANNELS = ("fx_piezo", "fy_piezo", "fx_strain", "fy_strain")
#: orbit / spin speed of the delay step: the spin's harmonics (runout, unbalance) stay off the
#: board's revolution harmonics and average out
DELAY_RATIO = 0.7
DELAY_RUN = "reference run"  # what the delay step's runs are called (up to 2143 rpm spin: no slow roll)


@dataclass(frozen=True)
class StepOptions:
    """What every step takes from the command line (operator units converted to SI)."""

    operator: str
    spin_rpm: float
    revolutions: int
    recess_pressure_mpa: float
    pressure_ratio: float
    sim: bool
    sim_config: Path | None
    speedup: float

    def roll(self) -> SlowRoll:
        return SlowRoll(self.spin_rpm * RPM, self.recess_pressure_mpa * MPA, self.pressure_ratio, self.revolutions)


class CalibrationOptionError(OrbitrigError):
    """An option of a calibration step the rig refuses before anything is sent (exit status 2)."""


def delay_rolls(opts: StepOptions, speeds_rpm: list[float]) -> list[SlowRoll]:
    """The DELAY_RUNs of `calibrate delay`: the orbit spindle at each speed, the spin at 1/DELAY_RATIO times it."""
    b = opts.roll()
    return [
        SlowRoll(rpm * RPM / DELAY_RATIO, b.recess_pressure, b.pressure_ratio, b.revolutions, DELAY_RATIO, DELAY_RUN)
        for rpm in speeds_rpm
    ]


def check_rolls(rig: RigConfig, rolls: list[SlowRoll], option: str) -> None:
    """Every slow roll of a step within the rig's drive limits, checked before anything is sent
    by the drives' own check (as `orbitrig drives run`); CalibrationOptionError naming the
    option, the speeds and the limit."""
    d = rig.drives
    limits = drive_limits(d)
    for roll in rolls:
        try:
            limits.check(roll.spin, roll.orbit, spin_id=d.spin_id, orbit_id=d.orbit_id)
        except DriveLimitError as err:
            raise CalibrationOptionError(
                f"{option}: {roll.name} at spin {rpm_text(roll.spin)}, orbit {rpm_text(roll.orbit)}: "
                f"{err} (the rig's [drives] in {rig.file}); nothing sent"
            ) from None


class OperatorLoads(AsksOperator):
    """The rig: the operator makes the slow roll's manual settings, applies each load (or connects the
    phase reference) and confirms on the terminal (Ctrl-C ends the step). Each prompt says whether the
    drives turn (`motion`: the step's session, `watch`); the input is taken off with both drives at
    standstill (orbitrig.run.calibration), and only told, not asked, after a step that did not complete.
    A prompt while the drives turn that nobody can answer (standard input not a terminal, as a sweep
    judges it, or one the command reads as a background job: `&`, `bg`) fails the step after
    [interlocks] unanswered_pause_s, as it stops an unattended sweep's pause: the step's way out then
    stops both drives. Brought to the foreground (`fg`), the prompt waits without that limit, as the
    sweep's pause (orbitrig.cli.calibrate_prompt.answered)."""

    def __init__(self) -> None:
        self.motion: Callable[[], str] = lambda: NOT_READ
        self.session: CalibrationSession | None = None
        self.manual: tuple[float, float, float, float] | None = None  # the settings last confirmed (SI)

    async def set_manual(
        self, *, orbit_radius: float, static_eccentricity: float, recess_pressure: float, pressure_ratio: float
    ) -> None:
        """Asked before the step's run without orbit starts the spindles (once for the same settings, as
        the delay step's speeds); no confirmation fails the step, spindles not started. Orbit radius m, pressure Pa."""
        settings = (orbit_radius, static_eccentricity, recess_pressure, pressure_ratio)
        if settings == self.manual:
            return
        what = (
            f"set orbit radius {micrometres(orbit_radius, 'g')}, static eccentricity {static_eccentricity:g}, "
            f"recess pressure {recess_pressure / MPA:g} MPa, pressure ratio {pressure_ratio:g} "
            "for the run without orbit (it starts both spindles)"
        )
        try:
            await self._ask(what)
        except CalibrationFailed as err:
            raise CalibrationFailed(f"{err}: the manual settings not confirmed, spindles not started") from None
        self.manual = settings

    def watch(self, session: CalibrationSession) -> None:
        self.motion, self.session = session.motion, session

    async def _ask(self, what: str) -> None:
        session, prompt = self.session, f"{self.motion()}: {what}, then press Enter"
        if session is None or not session.turning():
            await confirmed(prompt)
            return
        limit = session.rig.interlocks.unanswered_pause_s
        meanwhile = f"the step fails after {limit:g} s ([interlocks] unanswered_pause_s), both drives stopped"
        try:
            await confirmed(prompt, limit, meanwhile)
        except Unanswered:
            raise CalibrationFailed(
                f"nobody confirmed within {limit:g} s ([interlocks] unanswered_pause_s) with the drives "
                f"turning, standard input not a terminal or one it reads as a background job: nobody can "
                f"answer ({what})"
            ) from None

    async def apply_load(self, fx: float, fy: float) -> None:
        what = (
            REMOVE_LOADS
            if fx == 0 and fy == 0
            else f"apply the static load fx = {fx:+.1f} N, fy = {fy:+.1f} N on the journal"
        )
        await self._ask(what)

    async def apply_displacement(self, dx: float, dy: float) -> None:
        what = (
            REMOVE_STEP
            if dx == 0 and dy == 0
            else f"step the journal by x = {micrometres(dx, '+.2f')}, y = {micrometres(dy, '+.2f')} (micrometer)"
        )
        await self._ask(what)

    async def apply_reference(self, force: float, probe: float) -> None:
        what = (
            REMOVE_REFERENCE
            if force == 0 and probe == 0
            else (
                f"connect the phase reference (locked to the orbit spindle) to every channel's input: "
                f"{force:g} N on the force channels, {micrometres(probe, 'g')} on the probes"
            )
        )
        await self._ask(what)


def _watched(hands, session: CalibrationSession):
    """`hands`, its prompts saying the drives' state as `session` last read it."""
    if isinstance(hands, OperatorLoads):
        hands.watch(session)
    return hands


@contextlib.asynccontextmanager
async def rig_access(rig: RigConfig, opts: StepOptions):
    """(RigAccess, load hands) of the rig, or of a simulator started for the step."""
    if not opts.sim:
        from orbitrig.run.rig_answers import require_rig_answers

        await require_rig_answers(rig, "orbitrig calibrate ... --sim", "no record was written")
        hands = OperatorLoads()  # the operator's hands also make the slow roll's manual settings
        yield replace(RigAccess.of_rig(rig), hands=hands), hands
        return
    from orbitrig.cli.simulated_rig import simulated_rig
    from orbitrig.cli.scenarios import scenario_file
    from sim.scenario_files import load_sim_config

    path = scenario_file(opts.sim_config)
    try:
        config = load_sim_config(path) if path else None
    except ValueError as err:
        raise typer.BadParameter(str(err), param_hint="--sim-config") from None
    node = rig.transports.can_node_id  # the simulator's CAN node answers as the node rig.toml reads
    async with simulated_rig(opts.speedup, config, can_node_id=node) as (_, access):
        yield access, access.hands


def _base(rig: RigConfig, opts: StepOptions, step: RecordStep) -> dict:
    """The new record's fields from the active record (or rig.toml), its date and operator set,
    the rig's id and channel setup (orbitrig.config.identity); no reference standard (the
    step sets its own: an earlier step's is in the records before)."""
    from orbitrig.cli.scenarios import scenario_of
    from orbitrig.config import digest, identity
    from orbitrig.run.provenance import software_version

    old = rig.record
    scenario = scenario_of(opts.sim_config) if opts.sim else None  # a --sim step's: refused on the rig
    base = (
        old.model_dump(exclude={"reference"})
        if old is not None
        else {"uncertainty": (rig.calibration_uncertainty or CalibrationUncertainty()).model_dump()}
    )
    base.update(
        date=now_iso(),
        operator=opts.operator,
        step=step,
        previous=rig.calibration_record or "",
        software=software_version(),  # the code, as a run's provenance names it
        simulator=scenario.name if scenario else "",
        simulator_sha256=digest(scenario.text) if scenario else "",  # its content: compared by other_scenario
        **identity(rig),
    )
    return base


async def loads_record(
    rig: RigConfig, opts: StepOptions, load_n: float, reference: Reference, note
) -> CalibrationRecord:
    """`calibrate loads`: the default load set of `load_n` N, each system's gain matrix fitted.
    Values no record can hold (readings that do not follow the loads: none applied, a channel
    unplugged) fail the step, no record written."""
    from pydantic import ValidationError

    loads = static_loads(load_n)
    async with rig_access(rig, opts) as (access, hands):
        async with CalibrationSession(rig, access, note) as session:
            _watched(hands, session)  # its prompts, the manual settings' first, say the drives' state
            await session.roll(opts.roll())
            readings = await measure_loads(session, hands, loads)
    data = _base(rig, opts, RecordStep.LOADS)
    data["reference"] = reference.model_dump()
    data["loads"] = dict(data.get("loads") or {})
    u_ref = reference.uncertainty_pct / 100.0
    try:
        for lms in LMS:
            fit = fit_gain_matrix(loads, readings[lms], u_ref)
            k, big_u = expanded(fit.gain_u, fit.gain_u_fit, fit.dof)
            data["loads"][lms] = LoadGains(
                gain=fit.gain.tolist(),
                gain_u=fit.gain_u.tolist(),
                offset_n=fit.offset.tolist(),
                residual_n=fit.residual_rms,
                loads=len(loads),
                dof=fit.dof,
                gain_k=k.tolist(),
                gain_U=big_u.tolist(),
            ).model_dump(exclude_none=True)
            for axis, u in zip(("fx", "fy"), fit.relative_gain_u()):
                data["uncertainty"][f"{axis}_{lms}"]["gain_pct"] = float(u * 100.0)
        return CalibrationRecord.model_validate(data)
    except ValidationError as err:
        raise unrecordable("the fitted gain matrices", err, "were the loads applied as asked?") from None


async def runout_record(rig: RigConfig, opts: StepOptions, note) -> CalibrationRecord:
    """`calibrate runout`: every probe track's runout at 1x and 2x spin from a slow roll, its
    revolutions turned back by the spin's slip fitted from them (recorded; beyond SLIP_LIMIT the
    step fails, no record written)."""
    async with rig_access(rig, opts) as (access, hands):
        async with CalibrationSession(rig, access, note) as session:
            _watched(hands, session)  # its prompts, the manual settings' first, say the drives' state
            await session.roll(opts.roll())
            measured, n, fit = await measure_runout(session)
    if fit.unfitted:
        note(f"spin slip not fitted: {fit.unfitted}; the runout is each probe's plain mean of the revolutions")
    refused = slip_refused(fit)
    if refused:
        raise CalibrationFailed(refused)
    data = _base(rig, opts, RecordStep.RUNOUT)
    probes = {p: ProbeRunout.model_validate(measured[p]).model_dump(exclude_none=True) for p in PROBES}
    slip = {"slip_pct": fit.slip * 100.0, "slip_u_pct": fit.slip_u * 100.0} if np.isfinite(fit.slip_u) else {}
    runout = {"spin_rpm": opts.spin_rpm, "revolutions": n, **slip, **probes}
    data["runout"] = Runout.model_validate(runout).model_dump(exclude_none=True)
    return CalibrationRecord.model_validate(data)


def _inverted(rig: RigConfig, name: str, phase: float, lag: float) -> str:
    """The line saying that force channel `name` reads the reference inverted (fitted `phase`, `lag` rad)."""
    lms, i, rec = name.split("_")[1], int(name.startswith("fy")), rig.record
    g = f"{rec.force_gain(lms)[i][i]:+.4f}" if rec is not None and lms in rec.loads else "none yet"
    return (
        f"{name} reads the reference inverted ({np.degrees(phase):+.3f} deg): a sign, its gains' (rig.toml's; "
        f"the loads step's matrix: {g}), not a lag; recorded: the lag apart from it, {np.degrees(lag):+.4f} deg"
    )


async def delay_record(
    rig: RigConfig, opts: StepOptions, speeds_rpm: list[float], amplitudes: tuple[float, float], note
) -> CalibrationRecord:
    """`calibrate delay`: the phase reference read at each slow-roll speed; each force channel's and
    each probe's lag behind the probes' mean fitted as a constant phase plus a time delay
    (probe_delays: only the probes' differences are measurable). The sweep takes every recorded lag
    out, the probes' too (``probe_lags_corrected``), so each channel's [uncertainty] phase_deg and
    delay_us are the fit's standard uncertainties alone. A force channel reading the reference
    inverted takes its sign from its gains (rig.toml's, the loads step's matrix), never from a lag:
    the record holds the lag apart from it, and a line says so. Values no record can hold fail the
    step, no record written."""
    from pydantic import ValidationError

    rolls = delay_rolls(opts, speeds_rpm)
    async with rig_access(rig, opts) as (access, hands):
        async with CalibrationSession(rig, access, note) as session:
            freqs, lags = await measure_delay(session, _watched(hands, session), rolls, amplitudes)
    data = _base(rig, opts, RecordStep.DELAY)
    data["delay"], data["probe_lags_corrected"] = {}, True
    try:
        probes, delays = probe_delays(freqs, lags, note), {}  # a line per implausible probe lag
        for name in FORCE_CHANNELS:
            fit, delays[name] = fitted_delay(freqs, lags[name])
            if fit.polarity < 0:
                note(_inverted(rig, name, fit.phase, fit.lag))
        for name, d in {**delays, **probes}.items():
            data["delay"][name] = d.model_dump()
            data["uncertainty"][name].update(phase_deg=d.phase_u_deg, delay_us=d.delay_u_us)
        return CalibrationRecord.model_validate(data)
    except ValidationError as err:
        raise unrecordable("the fitted lags", err, "was the phase reference connected?") from None


async def probes_record(
    rig: RigConfig, opts: StepOptions, steps: np.ndarray, reference: Reference, note
) -> CalibrationRecord:
    """`calibrate probes`: known displacement steps along x, then y; each probe's gain and linearity.
    The reference (micrometer) is one error common to every probe: [uncertainty]'s
    ``probe_sensitivity_pct`` carries it, each probe's ``gain_pct`` the fit's own part only (the
    budget adds the two, so the reference counts once). Values no record can hold fail the step."""
    from pydantic import ValidationError

    async with rig_access(rig, opts) as (access, hands):
        async with CalibrationSession(rig, access, note) as session:
            _watched(hands, session)  # its prompts, the manual settings' first, say the drives' state
            await session.roll(opts.roll())
            readings = await measure_probes(session, hands, steps)
    data = _base(rig, opts, RecordStep.PROBES)
    data["reference"] = reference.model_dump()
    data["probes"] = {}
    try:
        for p in PROBES:
            fit = fit_probe(steps, readings[p], reference.uncertainty_pct / 100.0)
            k, big_u = expanded(np.array(fit.gain_u), np.array(fit.gain_u_fit), fit.dof)
            data["probes"][p] = dict(  # validated with the record: a refusal names the probe
                gain=fit.gain,
                gain_u=fit.gain_u,
                dof=fit.dof,
                gain_k=float(k),
                gain_U=float(big_u),
                linearity_pct=fit.linearity * 100,
                span_um=float(np.ptp(steps)) / UM,
                steps=len(steps),
            )
            data["uncertainty"][p]["gain_pct"] = fit.gain_u_fit / abs(fit.gain) * 100.0
        data["uncertainty"]["probe_sensitivity_pct"] = reference.uncertainty_pct
        return CalibrationRecord.model_validate(data)
    except ValidationError as err:
        raise unrecordable("the fitted probe gains", err, "was the journal stepped as asked?") from None
