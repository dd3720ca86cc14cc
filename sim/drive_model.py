"""Emulated spindle drive: the register map of docs/protocols/drive-modbus.md.

Pure logic, no I/O. One `DriveModel` is one drive (device id 1 = spin,
2 = orbit). The Modbus servers in `sim/modbus_server.py` route every request
to `read` / `write` and call `note_request` for every well-formed request
addressed to the drive; the rig reads `actual_rpm` after `advance()`.
The map, its parameter table, checks and reference limits are
`sim/drive_registers.py`; the control-word / status-word state machine and its
ramps are `sim/drive_states.py`; latched faults and the communication-loss
watchdog are `sim/drive_faults.py`; the motor side run in time (state, speed,
ramps, trips) is `sim/drive_motion.py`. This module is the drive's face: its
registers, the control words it takes, and its keypad.

Network control, parameter writes, the keypad: docs/simulator.md, "Drives".
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable, Sequence

from . import drive_registers as R
from .drive_faults import CommWatchdog, FaultLatch
from .drive_motion import DriveMotion
from .drive_states import ENABLED, FAULTED, INHIBITED, READY, status_word


class DriveModel(DriveMotion):
    """One emulated drive: register map, state machine, ramps, faults, watchdog.

    Parameters
    ----------
    device_id : Modbus device id (1 = spin, 2 = orbit); informational.
    clock : simulated time in seconds (monotonic, may stall).
    bidirectional : True for the orbit drive (negative REF = backward whirl),
        False for the spin drive (negative REF limited to 0, see module doc).
    wall_clock : wall time in seconds for the communication-loss watchdog; None (default):
        time.monotonic, as a real drive's. The simulator process (sim.rig) passes an AwakeClock
        (sim/clock.py: wall time without the stalls of the loop serving it), which the Modbus
        servers tick; a master sharing the process with the drives must not have its own
        stalls excused.
    coast_decel : rpm/s (simulated) at which an unpowered spindle slows down.
    rated_rpm, starting_time, friction : torque model; TORQUE is 100 % when
        accelerating at rated_rpm / starting_time rpm/s, plus `friction`
        (fraction of nominal torque) at rated_rpm, proportional to speed.
    """

    def __init__(
        self,
        device_id: int,
        *,
        clock: Callable[[], float],
        bidirectional: bool,
        wall_clock: Callable[[], float] | None = None,
        coast_decel: float = 150.0,
        rated_rpm: float = 3000.0,
        starting_time: float = 1.0,
        friction: float = 0.05,
        speed_error: float = 0.0,
    ) -> None:
        super().__init__(
            device_id,
            clock=clock,
            bidirectional=bidirectional,
            wall_clock=wall_clock,
            coast_decel=coast_decel,
            rated_rpm=rated_rpm,
            starting_time=starting_time,
            friction=friction,
            speed_error=speed_error,
        )
        self._cw_reg = 0  # last written CW (reads back)
        self.control_words: deque[tuple[float, int]] = deque(maxlen=64)  # (wall s, CW) of the last CW writes
        self._ref_reg = 0  # last written REF, int16
        self._ref2 = 0
        self._remote = False
        self._keypad = False  # the keypad holds control: control words refused (see local_control)
        self._alarm = False

    # ------------------------------------------------------------------ API
    @property
    def status_word(self) -> int:
        return self._status_word()

    def read(self, address: int, count: int) -> list[int]:
        """Function code 03: `count` registers from `address` as uint16."""
        addresses = R.check_read(address, count)
        self.advance()
        return [R.uint16(self._register(a)) for a in addresses]

    def write(self, address: int, values: Sequence[int]) -> None:
        """Function codes 06 / 16: write uint16 `values` from `address`, all or nothing. A write
        with CW while the keypad holds control is refused (exception 03) and changes nothing."""
        updates = R.check_write(address, values)
        self.advance()
        if R.CW in updates and self._keypad:
            raise R.DriveModbusException(R.ILLEGAL_VALUE, "control word refused: local control (the keypad has it)")
        params = {a: v for a, v in updates.items() if a in R.PARAMETER_DEFAULTS}
        if params:
            if self._modulating():
                raise R.DriveModbusException(R.ILLEGAL_VALUE, "parameter write while running")
            R.check_parameter_ranges(params)
            self._params.update(params)
            if R.COMM_LOSS_TIMEOUT in params:
                self._watchdog.feed(self._w, self._w_wall)  # a new timeout starts counting now
        if R.REF2 in updates:
            self._ref2 = R.int16(updates[R.REF2])
        if R.REF in updates:
            self._ref_reg = R.int16(updates[R.REF])
            if self._remote:
                self._ref = self._ref_reg
        if R.CW in updates:
            self.control_words.append((time.monotonic(), updates[R.CW]))
            self._write_cw(updates[R.CW])

    def inject_fault(self, code: int) -> None:
        """Trip with `code` (2310, 4210, 7301, 7510); its cause stays until cleared."""
        if code not in R.FAULT_REACTIONS:
            raise ValueError(f"unknown fault code {code}; known: {sorted(R.FAULT_REACTIONS)}")
        self.advance()
        self._faults.causes.add(code)
        self._trip(code)

    def power_cycle(self) -> None:
        """The drive's supply off and on again (a mains dip, its breaker): the spindle coasts, and
        the drive comes up as from power-on: switch-on inhibited, parameters at their defaults,
        CW, REF and REF2 0, no fault latched, its comm-loss watchdog not armed."""
        self.advance()
        self._params = dict(R.PARAMETER_DEFAULTS)
        self._cw_reg = self._cw = self._ref_reg = self._ref = self._ref2 = 0
        self._remote = self._local = self._keypad = self._fault_ramp = False
        self._faults, self._watchdog = FaultLatch(), CommWatchdog(self._w, self._w_wall)
        self._state = INHIBITED

    def set_alarm(self, on: bool) -> None:
        """Raise / clear the ALARM (warning) status bit."""
        self._alarm = bool(on)

    def local_control(self, rpm: float) -> None:
        """Local keypad: take control and run at `rpm` NOW, at setpoint (no ramp); 0 = stopped.

        The keypad holds control (SW.REMOTE = 0, watchdog disarmed): every write with CW is
        refused with exception 03 until `hand_back`. Raises ValueError for a negative speed on
        a one-direction drive, RuntimeError when tripped.
        """
        self.advance()
        if rpm < 0 and not self.bidirectional:
            raise ValueError(f"drive {self.device_id} turns one direction only (rpm >= 0)")
        if self._state == FAULTED:
            raise RuntimeError(f"drive {self.device_id} is tripped (fault {self.fault_code})")
        self._local = self._keypad = True
        self._remote = False
        self._watchdog.armed = False
        limit = float(self._params[R.MAX_SPEED])
        self._local_rpm = math.copysign(min(abs(float(rpm)), limit), rpm)
        self._speed = self._local_rpm
        self.trace.jump(self._t, self._speed)
        self._alpha = 0.0
        self._cw = R.CW_OFF2 | R.CW_OFF3 | R.CW_RAMP_OUT_ZERO | R.CW_RAMP_HOLD | R.CW_RAMP_IN_ZERO
        if rpm != 0:
            self._cw |= R.CW_OFF1 | R.CW_RUN
            self._state = ENABLED
        else:
            self._state = READY

    def hand_back(self) -> None:
        """The keypad gives control back to the network: the drive runs on at the keypad's speed
        (SW.REMOTE = 0) until it takes a control word with REMOTE = 1, which takes network control."""
        self.advance()
        self._keypad = False

    @property
    def keypad(self) -> bool:
        """The keypad holds control (local control): control words are refused."""
        return self._keypad

    # ------------------------------------------------------------ registers
    def _register(self, address: int) -> int:
        if address == R.CW:
            return self._cw_reg
        if address == R.REF:
            return self._ref_reg
        if address == R.REF2:
            return self._ref2
        if address == R.SW:
            return self._status_word()
        if address == R.ACT:
            return R.clip16(self._speed * R.REF_FULL_SCALE / self._params[R.SPEED_SCALE])
        if address == R.TORQUE:
            return R.clip16(10000.0 * self.torque)
        if address == R.FAULT:
            return self.fault_code
        return self._params[address]

    def _status_word(self) -> int:
        ref = self._local_rpm if self._local else self._ref * self._params[R.SPEED_SCALE] / R.REF_FULL_SCALE
        return status_word(
            self._state,
            self._cw,
            alarm=self._alarm,
            at_setpoint=abs(self._speed - ref) <= self._params[R.AT_SETPOINT_BAND],
            remote=self._remote,
            above_limit=self._limited_reference()[1],
        )

    # -------------------------------------------------------- state machine
    def _write_cw(self, value: int) -> None:
        self._cw_reg = value
        if not value & R.CW_REMOTE:
            self._remote = False  # stored, not acted on; the watchdog stays armed
            return
        self._watchdog.arm(self._w, self._w_wall)  # arming starts a fresh timeout
        self._remote = True
        self._local = False
        self._ref = self._ref_reg
        old, self._cw = self._cw, value
        if value & R.CW_RESET and not old & R.CW_RESET:
            self._reset_faults()
        self._evaluate()

    def _reset_faults(self) -> None:
        if self._state != FAULTED:
            return
        if self._faults.reset():
            self._fault_ramp = False
            self._state = INHIBITED
