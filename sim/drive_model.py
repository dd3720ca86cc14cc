"""Emulated spindle drive: the register map of docs/protocols/drive-modbus.md.

Pure logic, no I/O. One `DriveModel` is one drive (device id 1 = spin,
2 = orbit). The Modbus servers in `sim/modbus_server.py` route every request
to `read` / `write` and call `note_request` for every well-formed request
addressed to the drive; the rig reads `actual_rpm` after `advance()`.
The map, its parameter table, checks and reference limits are
`sim/drive_registers.py`; the control-word / status-word state machine and its
ramps are `sim/drive_states.py`; latched faults and the communication-loss
watchdog are `sim/drive_faults.py`. This module holds one drive's state and
runs it in time.

Timing (simulated ramps, a wall-clock watchdog), network control, parameter writes, coasting
and torque: docs/simulator.md, "Drives".
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable, Sequence

from . import drive_registers as R
from .drive_faults import CommWatchdog, FaultLatch
from .drive_states import (
    EMERGENCY_FACTOR,
    ENABLED,
    FAULTED,
    INHIBITED,
    OFF1_ACTIVE,
    OFF3_ACTIVE,
    READY,
    modulating,
    motion,
    ramp_phase,
    settle,
    status_word,
)
from .speed_trace import SpeedTrace


class DriveModel:
    """One emulated drive: register map, state machine, ramps, faults, watchdog.

    Parameters
    ----------
    device_id : Modbus device id (1 = spin, 2 = orbit); informational.
    clock : simulated time in seconds (monotonic, may stall).
    bidirectional : True for the orbit drive (negative REF = backward whirl),
        False for the spin drive (negative REF limited to 0, see module doc).
    wall_clock : wall time in seconds for the communication-loss watchdog.
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
        wall_clock: Callable[[], float] = time.monotonic,
        coast_decel: float = 150.0,
        rated_rpm: float = 3000.0,
        starting_time: float = 1.0,
        friction: float = 0.05,
        speed_error: float = 0.0,
    ) -> None:
        if coast_decel <= 0 or rated_rpm <= 0 or starting_time <= 0:
            raise ValueError("coast_decel, rated_rpm and starting_time must be > 0")
        self.device_id = device_id
        self.bidirectional = bidirectional
        self._clock = clock
        self._wall = wall_clock
        self._coast_decel = float(coast_decel)
        self._a_nom = rated_rpm / starting_time
        self._rated_rpm = float(rated_rpm)
        self._friction = float(friction)
        self._speed_error = float(speed_error)

        self._params = dict(R.PARAMETER_DEFAULTS)
        self._cw_reg = 0  # last written CW (reads back)
        self._cw = 0  # last accepted CW (REMOTE = 1)
        self.control_words: deque[tuple[float, int]] = deque(maxlen=64)  # (wall s, CW) of the last CW writes
        self._ref_reg = 0  # last written REF, int16
        self._ref = 0  # last accepted REF, int16
        self._ref2 = 0
        self._remote = False
        self._local = False
        self._local_rpm = 0.0
        self._alarm = False

        self._state = INHIBITED
        self._speed = 0.0  # rpm, signed
        self._alpha = 0.0  # rpm/s, current ramp acceleration (powered)
        self._faults = FaultLatch()
        self._fault_ramp = False  # 7510 ramp stop in progress
        self.comm_lost_after: float | None = None  # wall time of the last request before a 7510 trip
        self._fault_ramp_factor = 1.0  # x DECEL rate (EMERGENCY_FACTOR if OFF3 was active)
        # a ramp stop word during the emergency ramp resumes the slower ramp stop (sim/drive_states.py)
        self.off1_yields = False

        self._t = float(clock())
        self.trace = SpeedTrace(self._t)  # the speed over simulated time, for the spindles (sim.slot_stream)
        self._w = float(wall_clock())
        self._watchdog = CommWatchdog(self._w)

    # ------------------------------------------------------------------ API
    @property
    def actual_rpm(self) -> float:
        """Actual speed in rpm, signed, as of the last `advance()`."""
        return self._speed

    @property
    def running(self) -> bool:
        """Operation enabled (RDY_REF): running and following the reference."""
        return self._state == ENABLED

    @property
    def state(self) -> str:
        """State name of the drive-profile state machine."""
        return self._state

    @property
    def fault_code(self) -> int:
        """Active fault code (first latched), 0 = none."""
        return self._faults.code

    @property
    def faults(self) -> tuple[int, ...]:
        """All latched fault codes in order of occurrence."""
        return tuple(self._faults.latched)

    @property
    def torque(self) -> float:
        """Actual torque as a fraction of nominal (1.0 = 100 %)."""
        if not self._powered():
            return 0.0
        return self._alpha / self._a_nom + self._friction * self._speed / self._rated_rpm

    @property
    def reference_rpm(self) -> float:
        """The reference the ramp follows, rpm signed, after limiting."""
        return self._limited_reference()[0]

    @property
    def status_word(self) -> int:
        return self._status_word()

    def parameter(self, address: int) -> int:
        """Current value of parameter `address` (100..105)."""
        return self._params[address]

    def advance(self) -> None:
        """Integrate ramps and state up to `clock()`; run the watchdog (wall time)."""
        t_now = max(float(self._clock()), self._t)
        w_now = float(self._wall())
        frac = None
        if R.COMM_LOSS_FAULT not in self._faults.latched:
            frac = self._watchdog.expired(self._params[R.COMM_LOSS_TIMEOUT], self._w, w_now)
        if frac is not None:
            self.comm_lost_after = self._watchdog.last_request
            self._integrate_to(self._t + frac * (t_now - self._t))
            self._trip(R.COMM_LOSS_FAULT)
            self._faults.causes.add(R.COMM_LOSS_FAULT)
        self._integrate_to(t_now)
        self._w = max(w_now, self._w)

    @property
    def last_request(self) -> float:
        """Wall time of the last valid request addressed to this drive."""
        return self._watchdog.last_request

    def note_request(self) -> None:
        """A valid request addressed to this drive arrived: feed the watchdog."""
        self.advance()
        self._watchdog.feed(self._w)
        self._faults.causes.discard(R.COMM_LOSS_FAULT)

    def read(self, address: int, count: int) -> list[int]:
        """Function code 03: `count` registers from `address` as uint16."""
        addresses = R.check_read(address, count)
        self.advance()
        return [R.uint16(self._register(a)) for a in addresses]

    def write(self, address: int, values: Sequence[int]) -> None:
        """Function codes 06 / 16: write uint16 `values` from `address`, all or nothing."""
        updates = R.check_write(address, values)
        self.advance()
        params = {a: v for a, v in updates.items() if a in R.PARAMETER_DEFAULTS}
        if params:
            if self._modulating():
                raise R.DriveModbusException(R.ILLEGAL_VALUE, "parameter write while running")
            R.check_parameter_ranges(params)
            self._params.update(params)
            if R.COMM_LOSS_TIMEOUT in params:
                self._watchdog.feed(self._w)  # a new timeout starts counting now
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
        self._remote = self._local = self._fault_ramp = False
        self._faults, self._watchdog = FaultLatch(), CommWatchdog(self._w)
        self._state = INHIBITED

    def clear_fault_cause(self, code: int | None = None) -> None:
        """Remove the cause of fault `code` (all causes if None); a RESET edge still
        has to clear the latched fault."""
        self._faults.clear_cause(code)

    def set_alarm(self, on: bool) -> None:
        """Raise / clear the ALARM (warning) status bit."""
        self._alarm = bool(on)

    def local_control(self, rpm: float) -> None:
        """Local keypad: run at `rpm` NOW, at setpoint (no ramp); 0 = stopped.

        Network control is released (SW.REMOTE = 0, watchdog disarmed) until a
        control word with REMOTE = 1 is written. Raises ValueError for a
        negative speed on a one-direction drive, RuntimeError when tripped.
        """
        self.advance()
        if rpm < 0 and not self.bidirectional:
            raise ValueError(f"drive {self.device_id} turns one direction only (rpm >= 0)")
        if self._state == FAULTED:
            raise RuntimeError(f"drive {self.device_id} is tripped (fault {self.fault_code})")
        self._local = True
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

    def _limited_reference(self) -> tuple[float, bool]:
        """(reference rpm after limiting, whether it was limited)."""
        if self._local:
            return self._local_rpm, False
        return R.limit_reference(self._ref, self._params[R.SPEED_SCALE], self._params[R.MAX_SPEED], self.bidirectional)

    # -------------------------------------------------------- state machine
    def _write_cw(self, value: int) -> None:
        self._cw_reg = value
        if not value & R.CW_REMOTE:
            self._remote = False  # stored, not acted on; the watchdog stays armed
            return
        self._watchdog.arm(self._w)  # arming starts a fresh timeout
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

    def _evaluate(self) -> None:
        """Apply the accepted control word to the state (until stable)."""
        self._state = settle(self._state, self._cw, self._speed, off1_yields=self.off1_yields)

    def _trip(self, code: int) -> None:
        was_powered = self._powered()
        self._faults.latch(code)
        if R.FAULT_REACTIONS[code] == "coast":
            self._fault_ramp = False
        elif self._state != FAULTED:
            self._fault_ramp = was_powered and self._speed != 0.0
            # an emergency stop already under way keeps its faster ramp
            self._fault_ramp_factor = EMERGENCY_FACTOR if self._state == OFF3_ACTIVE else 1.0
        self._state = FAULTED

    def _modulating(self) -> bool:
        """Producing torque: parameters are locked."""
        return modulating(self._state, self._fault_ramp)

    def _powered(self) -> bool:
        return self._modulating()

    # ------------------------------------------------------------- dynamics
    def _motion(self) -> tuple[float | None, float, float]:
        """(target rpm or None = hold, accel rate, decel rate) for the current state."""
        scale = float(self._params[R.SPEED_SCALE])
        return motion(
            self._state,
            self._cw,
            reference=R.turning_speed(
                self._limited_reference()[0], self._speed_error, self._params[R.SPEED_SCALE], self._params[R.MAX_SPEED]
            ),
            accel=scale / (0.1 * self._params[R.ACCEL_TIME]),
            decel=scale / (0.1 * self._params[R.DECEL_TIME]),
            coast_decel=self._coast_decel,
            fault_ramp=self._fault_ramp,
            fault_ramp_factor=self._fault_ramp_factor,
        )

    def _integrate_to(self, t_end: float) -> None:
        remaining = t_end - self._t
        self._t = max(self._t, t_end)
        for _ in range(16):  # a few phases at most: zero crossing, stop, state change
            target, up, down = self._motion()
            if target is None or self._speed == target:
                self._alpha = 0.0
                if self._standstill_transition():
                    continue
                break
            self._speed, self._alpha, left = ramp_phase(self._speed, target, up, down, remaining)
            if left is None:
                break
            self.trace.add(self._t - left, self._speed)  # the phase's end: the slope changes
            remaining = left
            self._standstill_transition()
        self.trace.add(self._t, self._speed)

    def _standstill_transition(self) -> bool:
        """Finish a stop that reached zero speed; True if the state changed."""
        if self._speed != 0.0:
            return False
        if self._state == OFF1_ACTIVE:
            self._state = READY
            self._evaluate()
            return True
        if self._state == OFF3_ACTIVE:
            self._state = INHIBITED
            self._evaluate()
            return True
        if self._state == FAULTED and self._fault_ramp:
            self._fault_ramp = False
            return True
        return False
