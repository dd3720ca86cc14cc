"""One variable-speed drive on a Modbus link (docs/protocols/drive-modbus.md).

Speeds are rad/s here (signed on a bidirectional drive: > 0 forward); the
registers carry rpm scaled by the drive's own SPEED_SCALE, which is read from
the drive, never assumed. State changes go through the control word and are
confirmed on the status word.
"""

from __future__ import annotations

import asyncio
import math
import time
from collections.abc import Callable

from drives import registers as R
from drives.errors import (
    DriveError,
    DriveExceptionResponse,
    DriveFaultError,
    DriveLimitError,
    DriveTimeoutError,
    ErrorContext,
)
from drives.late import run_undone
from drives.local_control import said_local
from drives.link import Guard, ModbusLink
from drives.readings import DriveParameters, DriveStatus
from rigunits import RPM

__all__ = ["Drive", "DriveParameters", "DriveStatus"]


class Drive:
    """One drive: parameters, status, start/stop through CW/SW, references in rad/s.

    Parameters
    ----------
    link : the shared ModbusLink.
    device_id : Modbus device id.
    name : 'spin' or 'orbit' (for messages).
    bidirectional : whether negative speeds are allowed (orbit drive only).
    state_timeout : seconds to wait for the status word to confirm a state change.
    write_retries : further tries of an idempotent write (CW, REF, parameters)
        after a request timeout or a broken connection (on a new one); an exception response is
        an answer, never retried.
    read_retries : further tries of a read after a request timeout or a broken connection (one late
        answer is not a fault); the poll reads without them, its own count of
        failed polls in a row bounds the time to declare the link lost.
    """

    def __init__(
        self,
        link: ModbusLink,
        device_id: int,
        name: str,
        *,
        bidirectional: bool,
        state_timeout: float = 2.0,
        write_retries: int = 2,
        read_retries: int = 1,
    ):
        if write_retries < 0 or read_retries < 0:
            raise ValueError(f"write_retries {write_retries} or read_retries {read_retries} is negative")
        self.write_retries = int(write_retries)
        self.read_retries = int(read_retries)
        self.link = link
        self.device_id = device_id
        self.name = name
        self.bidirectional = bidirectional
        self.state_timeout = state_timeout
        self.params: DriveParameters | None = None
        self._scale_rpm: int | None = None
        self._max_rpm: int | None = None
        self.run_sent = False  # a run word went out to it (answered or not): something may have started

    def _kw(self, register: int | None = None, fault_code: int | None = None) -> ErrorContext:
        return {
            "drive": self.device_id,
            "drive_name": self.name,
            "register": register,
            "fault_code": fault_code,
        }

    # -- parameters -------------------------------------------------------------
    async def read_parameters(self) -> DriveParameters:
        """Read the parameter block; the scaling of every later speed comes from it."""
        first, count = R.PARAMETERS
        words = await self.link.read(self.device_id, first, count, retries=self.read_retries)
        if words[0] == 0:
            raise DriveFaultError("SPEED_SCALE reads 0", **self._kw(R.SPEED_SCALE))
        self._scale_rpm, self._max_rpm = words[0], words[1]
        self.params = DriveParameters.from_words(words)
        return self.params

    async def configure(
        self,
        *,
        accel_time: float | None = None,
        decel_time: float | None = None,
        comm_loss_timeout: float | None = None,
        at_setpoint_band: float | None = None,
    ) -> DriveParameters:
        """Write the given parameters (s, s, s, rad/s); the drive must not be running.

        One parameter goes out as a write-single (FC06); several go out in one
        write-multiple (FC16) over the contiguous range from the lowest to the
        highest address given, gaps keeping the values just read, all or nothing.
        A drive that is running, or finds a value out of its range, answers
        exception 03 (DriveExceptionResponse) and changes none of them.
        """
        given: dict[int, int] = {}
        for address, value, unit in (
            (R.ACCEL_TIME, accel_time, R.TIME_UNIT),
            (R.DECEL_TIME, decel_time, R.TIME_UNIT),
            (R.COMM_LOSS_TIMEOUT, comm_loss_timeout, R.TIME_UNIT),
            (R.AT_SETPOINT_BAND, at_setpoint_band, RPM),
        ):
            if value is None:
                continue
            word = R.counts(value, unit)  # the drive refuses values outside its range (exc. 03)
            if not 0 <= word <= 0xFFFF:
                raise DriveLimitError(f"{value:g} does not fit the register (unit {unit:g})", **self._kw(address))
            given[address] = word
        if given:
            # One request over the contiguous range (gaps keep the values just read): FC06
            # for one word, FC16 for more, so a refusal (exception 03) changes nothing.
            first_p, count_p = R.PARAMETERS
            current = await self.link.read(self.device_id, first_p, count_p, retries=self.read_retries)
            first, last = min(given), max(given)
            words = [given.get(a, current[a - first_p]) for a in range(first, last + 1)]
            await self.link.write(self.device_id, first, words, retries=self.write_retries)
        return await self.read_parameters()

    # -- status -----------------------------------------------------------------
    async def read_status(self, *, retries: int | None = None, gives_way: bool = False) -> DriveStatus:
        """Read CW..FAULT in one request (also the watchdog heartbeat for this drive);
        retried after a timeout `read_retries` times by default; `gives_way` (the poll's
        reads): given up for a stop that needs the link (`ModbusLink.read`)."""
        if self._scale_rpm is None:
            await self.read_parameters()
        scale, _ = self._scales()
        first, count = R.PROCESS_DATA
        retries = self.read_retries if retries is None else retries
        asked = time.monotonic()
        w = await self.link.read(self.device_id, first, count, retries=retries, gives_way=gives_way)
        ref, act = R.from_word(w[R.REF]), R.from_word(w[R.ACT])
        return DriveStatus(
            name=self.name,
            device_id=self.device_id,
            control_word=w[R.CW],
            reference=R.ref_to_rpm(ref, scale) * RPM,
            status_word=w[R.SW],
            actual=R.ref_to_rpm(act, scale) * RPM,
            torque=R.from_word(w[R.TORQUE]) / R.TORQUE_FULL_SCALE,
            fault_code=w[R.FAULT],
            time=time.monotonic(),
            reference_raw=ref,
            actual_raw=act,
            asked=asked,
        )

    # -- references -------------------------------------------------------------
    def reference_for(self, speed: float) -> int:
        """Raw REF for `speed` rad/s, or DriveLimitError (direction, MAX_SPEED, int16).

        Pure check against the parameters read from the drive; nothing is sent. The
        REF is rounded to the nearest count that does not exceed MAX_SPEED.
        """
        scale, max_rpm = self._scales()
        if not math.isfinite(speed):
            raise DriveLimitError(f"speed {speed} rad/s is not finite", **self._kw(R.REF))
        if speed < 0 and not self.bidirectional:
            raise DriveLimitError(
                f"speed {speed:.3f} rad/s is negative; this drive turns one way only",
                **self._kw(R.REF),
            )
        rpm = speed / RPM
        if abs(rpm) > max_rpm + 1e-9:
            raise DriveLimitError(
                f"speed {speed:.3f} rad/s ({rpm:.1f} rpm) exceeds the drive's MAX_SPEED of {self._max_rpm} rpm",
                **self._kw(R.MAX_SPEED),
            )
        try:
            raw = R.rpm_to_ref(rpm, scale)
        except ValueError as err:
            raise DriveLimitError(str(err), **self._kw(R.REF)) from err
        if abs(R.ref_to_rpm(raw, scale)) > max_rpm:
            # rounded past MAX_SPEED: one count back, so the drive never clamps the REF it is
            # given (a clamped REF is never reached: AT_SETPOINT compares ACT with REF as written)
            raw -= 1 if raw > 0 else -1
        return raw

    def speed_of(self, raw: int) -> float:
        """rad/s of a raw REF/ACT value."""
        return R.ref_to_rpm(raw, self._scales()[0]) * RPM

    def _scales(self) -> tuple[int, int]:
        """(SPEED_SCALE, MAX_SPEED) in rpm as read from the drive; DriveError before they are read."""
        if self._scale_rpm is None or self._max_rpm is None:
            raise DriveError("parameters not read yet", **self._kw(R.SPEED_SCALE))
        return self._scale_rpm, self._max_rpm

    async def write_reference(
        self, raw: int, *, retries: int | None = None, urgent: bool = False, guard: Guard = None
    ) -> None:
        """Write REF (idempotent: retried on a timeout or a broken connection, `write_retries` times
        by default);
        `urgent`: before every request waiting for the link (a stop); `guard`: ModbusLink.write's."""
        retries = self.write_retries if retries is None else retries
        await self.link.write(self.device_id, R.REF, [R.to_word(raw)], retries=retries, urgent=urgent, guard=guard)

    # -- state machine ----------------------------------------------------------
    async def write_control(
        self, word: int, *, retries: int | None = None, urgent: bool = False, guard: Guard = None
    ) -> None:
        """Write CW (idempotent: retried on a timeout or a broken connection, `write_retries` times
        by default);
        `urgent`: before every request waiting for the link (a stop); `guard`: ModbusLink.write's."""
        retries = self.write_retries if retries is None else retries
        await self.link.write(self.device_id, R.CW, [word], retries=retries, urgent=urgent, guard=guard)

    async def ready(self, *, guard: Guard = None) -> None:
        """The ready word (0x0476) a start writes first; refused by a drive in local control:
        DriveInLocalControl (RigDrives.set_speeds gives it to every drive it starts before any run word)."""
        await self._command(R.CW_READY, guard)

    async def _command(self, word: int, guard: Guard = None) -> None:
        """`write_control` of a start's `word`; refused by a drive in local control: DriveInLocalControl."""
        try:
            await self.write_control(word, guard=guard)
        except DriveExceptionResponse as err:
            local = await said_local(self, err, word)
            if local is err:
                raise
            raise local from err

    async def wait_status(
        self,
        ok: Callable[[DriveStatus], bool],
        what: str,
        *,
        timeout: float | None = None,
        fail_on_trip: bool = True,
        refused: Callable[[DriveStatus], DriveError | None] = lambda st: None,
    ) -> DriveStatus:
        """Read the status word until `ok(status)`; DriveFaultError if the drive trips; what
        `refused(status)` returns, raised at once (a state that can no longer come)."""
        timeout = self.state_timeout if timeout is None else timeout
        deadline = time.monotonic() + timeout
        while True:
            st = await self.read_status()
            if ok(st):
                return st
            if (no := refused(st)) is not None:
                raise no
            if st.tripped and fail_on_trip:
                raise DriveFaultError(f"tripped while waiting for {what}", **self._kw(R.FAULT, st.fault_code))
            if time.monotonic() >= deadline:
                raise DriveTimeoutError(
                    f"{what} not reached within {timeout:g} s (status word 0x{st.status_word:04X}: {st.state})",
                    **self._kw(R.SW),
                )
            await asyncio.sleep(0.02)

    async def start(self, raw_ref: int, status: DriveStatus | None = None, *, guard: Guard = None) -> DriveStatus:
        """Run at raw reference `raw_ref`: REF, then CW ready -> RDY_ON, CW run -> RDY_REF; a
        drive running already takes the REF alone, none if it reads `raw_ref` back.

        `status`: a status just read (else it is read here). A tripped drive is refused with
        DriveFaultError (reset it first). `guard`: each word's (ModbusLink.write): none goes out
        once it says no (DriveSuperseded: a stop was asked after the start).
        """
        st = status if status is not None else await self.read_status()
        if st.tripped:
            raise DriveFaultError("tripped; reset the fault before starting", **self._kw(R.FAULT, st.fault_code))
        if st.following:
            if st.reference_raw != raw_ref:
                await self.write_reference(raw_ref, guard=guard)
            return st
        await self.write_reference(raw_ref, guard=guard)
        await self._command(R.CW_READY, guard)
        st = await self.wait_status(
            lambda s: bool(s.status_word & R.SWBit.RDY_ON) and not s.tripped, "ready to switch on"
        )
        if not st.remote:
            raise DriveFaultError(
                "does not accept network control (status word REMOTE = 0; local control?)",
                **self._kw(R.SW),
            )
        self.run_sent = True
        await self._command(R.CW_RUN, guard)
        enabled = "operation enabled (RDY_REF)"  # not once our own stop word given up reads back after the run word
        return await self.wait_status(
            lambda s: s.running, enabled, refused=lambda s: run_undone(s, self.link.late, enabled)
        )

    async def reset_fault(self) -> DriveStatus:
        """RESET edge: 0x0476, 0x04F6, 0x0476; DriveFaultError if the fault is still active.

        The leading 0x0476 (RESET = 0) makes sure there is a 0 -> 1 edge even when
        the drive still holds a control word with RESET = 1 (a client that died
        between its two reset writes).
        """
        st = await self.read_status()
        if not st.tripped:
            return st
        code = st.fault_code
        await self.write_control(R.CW_READY)
        await self.write_control(R.CW_RESET)
        await self.write_control(R.CW_READY)
        try:
            return await self.wait_status(
                lambda s: not s.tripped,
                "fault cleared",
                timeout=min(self.state_timeout, 0.5),
                fail_on_trip=False,
            )
        except DriveTimeoutError as err:
            raise DriveFaultError("fault reset refused: the cause is still active", **self._kw(R.FAULT, code)) from err
