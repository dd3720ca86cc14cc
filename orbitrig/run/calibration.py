"""Calibration steps on the rig: the session of a slow roll without orbit.

The A/D board converts on the orbit spindle's timing disk, so the orbit spindle turns during
every step; "without orbit" means the orbit radius (a manual setting) is zero. The slow roll
runs spin and orbit spindle at the same speed (ratio 1): then the spin's harmonics are the
board's revolution harmonics and the probe tracks' runout at 1x and 2x spin is the average's
first and second harmonic. Both drives are stopped on every way out (`CalibrationSession`),
before the links close. What each step measures: orbitrig.run.calibration_measure.

The input a step puts on the rig (loads, a displacement step, the phase reference) is taken off
only once both drives are confirmed at standstill (`CalibrationSession.applied`): the drives are
never left turning while the operator is asked something. While the drives turn, every hold,
acquisition and prompt for a load or a step is raced against the drives' poll
(`CalibrationSession.watched`: `RigDrives.check` and the link, as `orbitrig drives run --hold`
watches them) and the run's interlocks (orbitrig.run.supervision, sampled in a task of its own
for the whole session, as during a sweep): a drive that trips (both already commanded to stop by
the poll), a lost link to the drives, or an interlock that suspends a sweep and drops its block
(the lubricant supply lost: pump off, supply below its minimum; the CAN sensor node lost or mute,
daq.aux.LOST_AFTER), as soon as the sweep drops its block, not after supply_lost_timeout_s or
can_heartbeat_timeout_s (no reading of a record is taken without supply or without the node's
interlocks), ends the step within a poll interval, naming the drive and its fault,
the lost link or the interlock; the session's way out then stops both drives (the emergency
stop). A slow roll is not started once such an interlock has failed, nor before the recess
pressure and the pressure ratio (supply) read from CAN meet the step's, as a sweep checks them
before it spins (orbitrig.run.verification.pressures_settled). SI throughout.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import AsyncIterator, Awaitable
from dataclasses import dataclass
from functools import partial
from typing import Callable

from pydantic import ValidationError

from daq.averager import AveragedBlock
from daq.aux import AuxState
from daq.errors import DaqError
from drives.errors import DriveError
from drives.state import NOT_READ, RigDriveState
from drives.stop_said import stop_kind
from orbitrig.config import RigConfig
from orbitrig.run.averaging import acquire_waits, roll_rule
from orbitrig.run.calibration_checks import CalibrationChecks, CalibrationFailed, interlock_failed
from orbitrig.run.rig_io import RigAccess, RigIO
from orbitrig.run.safe_stop import not_confirmed, stop_shielded
from orbitrig.run.stop_words import send_stop_words
from orbitrig.run.supervision import InterlockSupervisor
from orbitrig.run.verification import pressures_settled
from rigunits import rpm_text

log = logging.getLogger(__name__)
HOLD_REVOLUTIONS = 3  # read and dropped after a change at the input


def unrecordable(what: str, err: ValidationError, hint: str = "") -> CalibrationFailed:
    """The failure of a step whose measured values no record can hold (``err``: pydantic's
    ValidationError): each field with its value and its limit on one line, not pydantic's text
    (lines, URLs); ``hint`` says what the operator may have missed."""
    fields = "; ".join(
        f"{'.'.join(map(str, e['loc']))} = {e['input']:.4g}: {e['msg'].lower()}"
        if isinstance(e.get("input"), (int, float))
        else f"{'.'.join(map(str, e['loc']))}: {e['msg'].lower()}"
        for e in err.errors(include_url=False)
    )
    return CalibrationFailed(f"{what} cannot be recorded ({fields}); {hint + ' ' if hint else ''}no record written")


class AsksOperator:
    """Hands that ask the operator at the terminal (on the rig) and wait for the answer. After a
    step that did not complete they are not asked to take the input off: the step ends at once,
    both drives at standstill, saying what is left on the rig (`CalibrationSession.applied`)."""


@dataclass(frozen=True)
class SlowRoll:
    """The slow roll of a step: spin (rad/s; the orbit spindle at ``ratio`` times it, radius zero),
    the pressures set meanwhile (Pa, -) and the revolutions averaged per reading; ``name``: what the
    operator is told it is (the delay step's runs reach thousands of rpm: no slow roll)."""

    spin: float
    recess_pressure: float
    pressure_ratio: float
    revolutions: int = 50
    ratio: float = 1.0
    name: str = "slow roll"

    @property
    def orbit(self) -> float:
        """The orbit spindle's speed (rad/s), the board's revolution rate."""
        return self.spin * self.ratio


class CalibrationSession(CalibrationChecks):
    """The rig opened for a calibration step; ``async with`` it, then `roll` and `average` (each
    wait raced against the drives' poll and the interlocks: CalibrationChecks)."""

    def __init__(self, rig: RigConfig, access: RigAccess, note: Callable[[str], None] = log.info):
        self.rig, self.access, self.note = rig, access, note
        self.io = RigIO(rig, access.endpoints)
        self.roll_spec: SlowRoll | None = None
        #: rad/s, spin and orbit as the last `roll` wrote them to the drives (each REF rounded to its count)
        self.written: tuple[float, float] | None = None
        self.at_standstill = False  # both drives confirmed at standstill since the last `roll`
        self.commanded = False  # a `roll` commanded both drives to turn
        self.unconfirmed: CalibrationFailed | None = None  # a stop that was not confirmed
        #: the run's interlocks (CAN node, lubricant supply, drives), sampled while the rig is open
        self.interlocks = InterlockSupervisor(self._sensors, rig.interlocks, interlock_failed)
        self._watching: asyncio.Task[None] | None = None

    async def __aenter__(self) -> "CalibrationSession":
        try:
            await self.io.__aenter__()
        except asyncio.CancelledError:  # the drives' entry let go of their link at once (drives/entry.py)
            said, missed = await self._stop_words()
            if missed:  # nothing may say the drives were stopped
                raise CalibrationFailed(f"interrupted while opening the rig; {said}; {missed}") from None
            self.note(f"interrupted while opening the rig; {said}")
            raise
        except (DriveError, DaqError, OSError) as err:
            raise CalibrationFailed(f"cannot open the rig: {err}") from err
        self._watching = asyncio.create_task(self.interlocks.watch(), name="calibration-interlocks")
        return self

    def _sensors(self) -> tuple[AuxState, RigDriveState]:
        """What the interlocks read: the CAN node's latest values, the drives' latest poll."""
        return self.io.open_aux.latest(), self.io.open_drives.state

    async def _stop_words(self) -> tuple[str, str]:
        """An opening cancelled (a signal): the ramp stop words (OFF1) to each drive that answers,
        over a link of the session's own, the emergency stop (OFF3) if a drive reads in its
        emergency ramp first or a further signal comes (orbitrig.run.stop_words). (What went out,
        what the reads first found, which drives took it, why a drive did not: 'drives not
        confirmed stopped: ...', or '' when both took it.)"""
        sent = await send_stop_words(self.access.endpoints.modbus_url, self.rig.drives)
        again = "interrupted again during the ramp stop: emergency stop (OFF3)"
        said = again if sent.escalated else stop_kind(sent.emergency, sent.read)
        missed = "; ".join(not_confirmed(err) for err in sent.errors)
        return f"{said} sent; stop word delivered to: {', '.join(sent.took) or 'no drive'}", missed

    async def __aexit__(self, *exc) -> None:
        """Both drives stopped and confirmed at standstill (`stop`: an emergency stop after an
        exception or a cancellation), then the links closed; a stop not delivered or not confirmed
        fails the step (CalibrationFailed: no record is written, and nothing says the drives were
        stopped), whatever ended it, also a cancellation while the links close; the step's own
        failure (a trip, a lost link) is said first. A failure closing the links after either
        (the drives' own exit stop not delivered) is noted, never said instead of them."""
        failed: CalibrationFailed | None = None
        if self._watching is not None:  # (what trips during the stop ends nothing more)
            self._watching.cancel()
        try:
            await self.stop(emergency=exc[0] is not None)
        except CalibrationFailed as err:
            failed = _joined(err, exc[1])
        finally:
            try:
                await self.io.__aexit__(*exc)
            except asyncio.CancelledError:
                if failed is None:
                    raise
            except (DriveError, DaqError, OSError) as err:  # the drives' own exit stop not delivered
                if failed is None and exc[0] is None:
                    raise
                self.note(f"closing the rig: {err}")  # what ended the step is said, not this
        if failed is not None:
            raise failed

    async def stop(self, *, emergency: bool = False) -> None:
        """Ramp (`emergency`: OFF3) both drives to zero and wait for standstill, shielded from a
        cancellation (orbitrig.run.safe_stop.stop_shielded: a cancellation during the stop does
        not cut it short, it makes it the emergency stop and is raised again once both drives
        are confirmed at standstill); says so once confirmed. Nothing to do once confirmed (until
        the next `roll`); a stop not confirmed raises CalibrationFailed, now and on every call."""
        if self.io.drives is None or self.at_standstill:
            return
        if self.unconfirmed is not None:
            raise self.unconfirmed
        timeout = self.access.time_scale.wall(self.rig.drives.stop_timeout_s) + 5.0
        try:
            await stop_shielded(self.io.drives, asyncio.Event(), emergency=emergency, timeout=timeout)
        except asyncio.CancelledError:
            self.at_standstill = True
            self.note("both drives stopped (a signal during the stop made it an emergency stop)")
            raise
        except DriveError as err:
            self.note(f"stopping the drives failed: {err}")
            self.unconfirmed = CalibrationFailed(not_confirmed(err))
            raise self.unconfirmed from err
        self.at_standstill = True
        self.note("both drives stopped")

    def turning(self) -> bool:
        """Both drives commanded to turn and not confirmed at standstill since."""
        return self.commanded and not self.at_standstill

    def motion(self) -> str:
        """Whether the spindles turn, as the drives last read: 'both drives at standstill' or the
        actual speeds (for the operator's prompts)."""
        return self.io.drives.state.motion() if self.io.drives is not None else NOT_READ

    @contextlib.asynccontextmanager
    async def applied(self, remove: Callable[[], Awaitable[None]], what: str, hands: object) -> AsyncIterator[None]:
        """An input (loads, a displacement step, the phase reference) on the rig while the body
        runs. On every way out both drives are stopped and confirmed at standstill first, only
        then is the input taken off: ``remove()`` (on the rig the operator's prompt, `what`).
        After a body that did not complete (an exception, a cancellation: the stop is then the
        emergency stop) hands that ask the operator (`AsksOperator`) are not asked: the step
        ends at once, with a line saying the drives' state and `what` is left to do. A stop not
        confirmed raises CalibrationFailed and nobody is asked anything."""
        completed = False
        try:
            yield
            completed = True
            await self.stop()  # a signal during it: the emergency stop, and the step did not complete
        except BaseException as err:
            try:
                await self.stop(emergency=True)
            except CalibrationFailed as failed:
                raise _joined(failed, err) from failed
            finally:
                if self.at_standstill:
                    await self._left_on(remove, what, hands, completed)
            raise
        await remove()

    async def _left_on(
        self, remove: Callable[[], Awaitable[None]], what: str, hands: object, measured: bool = False
    ) -> None:
        """The input of a step that did not complete (`measured`: its readings were taken, the
        closing stop was cut short), both drives at standstill: the operator is told (not asked:
        the step is ending), other hands take it off."""
        if isinstance(hands, AsksOperator):
            why = "the step ended during the closing stop" if measured else "the step did not complete"
            self.note(f"{self.motion()}: {what} ({why})")
            return
        try:
            await remove()
        except Exception as err:  # noqa: BLE001 - the step ends with its own failure
            self.note(f"{what} failed: {err}")

    async def roll(self, roll: SlowRoll) -> None:
        """Orbit radius and static eccentricity zero, the pressures set (by the access's hands: on
        the rig the operator is asked and confirms, or the step fails here, no drive started), then
        spin and orbit spindle at their speeds until both hold them."""
        self.roll_spec, self.written = roll, None
        await self.access.hands.set_manual(
            orbit_radius=0.0,
            static_eccentricity=0.0,
            recess_pressure=roll.recess_pressure,
            pressure_ratio=roll.pressure_ratio,
        )
        scale, s, drives = self.access.time_scale, self.rig.settle, self.io.open_drives
        self.check_interlocks()  # no spindle started once an interlock has failed
        await self._pressures_met(roll)
        self.at_standstill, self.commanded = False, True
        try:
            self.written = await drives.set_speeds(roll.spin, roll.orbit)
            settled = partial(drives.wait_settled, hold=scale.wall(s.hold_s), timeout=scale.wall(s.timeout_s) + 5.0)
            await self.watched(settled, self.check_interlocks)
        except DriveError as err:
            raise CalibrationFailed(
                f"{roll.name} at spin {rpm_text(roll.spin)}, orbit {rpm_text(roll.orbit)}: {err}"
            ) from err
        self.note(f"{roll.name}: spin {rpm_text(roll.spin)}, orbit spindle {rpm_text(roll.orbit)}, held")

    async def _pressures_met(self, roll: SlowRoll) -> None:
        """The supply and recess pressures checked against the step's, as a sweep checks them before
        it spins (`pressures_settled`); CalibrationFailed naming what is off, no spindle started."""
        aux = self.io.open_aux
        problems = await pressures_settled(aux.latest, roll, self.rig.verify, self.access.time_scale)
        if problems:
            raise CalibrationFailed(
                f"pressures not met before the {roll.name}: " + "; ".join(problems) + f"; {roll.name} not started"
            )
        self.note(f"pressures verified before the {roll.name}")

    async def hold(self) -> None:
        """After a change at the input (a load, the reference): `settle.hold_s` physical seconds,
        then a few revolutions read and dropped, so that no average holds what came before; both
        watched (`watched`)."""
        await self.watched(lambda: asyncio.sleep(self.access.time_scale.wall(self.rig.settle.hold_s)))
        await self.average(HOLD_REVOLUTIONS)

    async def average(self, revolutions: int | None = None) -> AveragedBlock:
        """One block of `revolutions` (default `roll.revolutions`) at the slow roll (retried once),
        each attempt watched (`watched`): a drive trip or a lost link ends it at once. Its spin
        tones are taken out at the spin turns of the speeds as written to the drives, and its
        off-speed revolutions judged against the orbit speed as written (as a sweep's block:
        orbitrig.run.averaging.roll_rule), not at the asked ones."""
        roll, av = self.roll_spec, self.rig.averaging
        if roll is None:
            raise CalibrationFailed("no slow roll set before the averaging: a step out of order")
        n = revolutions or roll.revolutions
        timeout, silence = acquire_waits(av, roll.orbit, n, self.access.time_scale.wall)
        rule = roll_rule(n, roll.spin, roll.orbit, av.speed_tolerance, self.written)
        for attempt in range(av.retries + 1):
            try:
                return await self.watched(lambda: self.io.acquire(rule, timeout=timeout, silence=silence))
            except (DaqError, TimeoutError) as err:
                self.note(f"acquisition failed ({type(err).__name__}: {err})")
                if attempt == av.retries:
                    raise CalibrationFailed(f"no block at the slow roll: {err}") from err
        raise AssertionError("unreachable")


def _joined(failed: CalibrationFailed, cause: BaseException | None) -> CalibrationFailed:
    """`failed` (the drives not confirmed stopped) after the step's own failure `cause` (a trip,
    a lost link: CalibrationFailed) that made it stop them: both said, the cause first."""
    if isinstance(cause, CalibrationFailed) and str(failed) not in str(cause):
        return CalibrationFailed(f"{cause}; {failed}")
    return failed
