"""Emulated spindle drive: the register map of docs/protocols/drive-modbus.md.

Pure logic, no I/O. One `DriveModel` is one drive (device id 1 = spin,
2 = orbit). The Modbus servers in `sim/modbus_server.py` route every request
to `read` / `write` and call `note_request` for every well-formed request
addressed to the drive; the rig reads `actual_rpm` after `advance()`.

Time
----
Speeds, ramps and coasting run in SIMULATED time, read from the `clock`
callable (seconds; the rig's speed-up clock). The communication-loss watchdog
runs in WALL time (`wall_clock`, default `time.monotonic`), as on a real
network. State is integrated lazily: `read`, `write`, `note_request`,
`inject_fault` and `local_control` first call `advance()`, so a value read over
Modbus is always current; the properties report the state as of the last
`advance()`. When the watchdog expired between two calls, the simulated time
of the expiry is interpolated between them, so the ramp stop starts where it
should even if nobody called `advance()` in the meantime.

State machine (common drive profile, control word / status word)
----------------------------------------------------------------
States: SWITCH-ON INHIBITED (power-up, after OFF2/OFF3, after a fault reset
with OFF1 still 1), READY TO SWITCH ON, READY TO OPERATE, OPERATION ENABLED,
OFF1 ACTIVE (ramp stop), OFF3 ACTIVE (emergency ramp stop), FAULT.

- 0x0476 (OFF1 = 0, OFF2 = OFF3 = 1): INHIBITED -> READY TO SWITCH ON. A
  start needs this step: 0x047F written straight after power-up, an OFF2/OFF3
  stop or a fault reset leaves the drive inhibited (no restart by surprise).
- OFF1 = 1: READY TO SWITCH ON -> READY TO OPERATE; with RUN = 1 as well
  -> OPERATION ENABLED: the speed follows REF along the ramps.
- OFF1 = 0 while enabled: ramp stop at DECEL_TIME (OFF1 ACTIVE), then READY
  TO SWITCH ON. OFF1 = 1 again during the ramp stop resumes operation.
- OFF2 = 0: coast stop at once (torque off), SWITCH-ON INHIBITED, OFF_2_STA = 0.
- OFF3 = 0 while under torque: emergency ramp stop 10 x faster than
  DECEL_TIME (OFF3 ACTIVE, OFF_3_STA = 0), then SWITCH-ON INHIBITED.
- RUN = 0 while enabled: pulses inhibited, the spindle coasts (READY TO
  OPERATE); RUN = 1 again restarts from the current (coasting) speed.
- RAMP bits 4..6 (all 1 in normal operation): bit 4 = 0 forces the ramp
  output to zero (stop at the emergency rate), bit 5 = 0 holds the ramp (speed
  frozen), bit 6 = 0 forces the ramp input to zero (stop along DECEL_TIME).
- RESET (bit 7) 0 -> 1 edge: clears every latched fault whose cause is gone;
  when none is left the drive goes to SWITCH-ON INHIBITED and, since the reset
  word 0x04F6 has OFF1 = 0, straight on to READY TO SWITCH ON.
- REMOTE (bit 10) = 0: the control word is stored (reads back) but not acted
  on; the drive keeps its last accepted command and reference and SW.REMOTE = 0,
  but the watchdog stays armed: a drive running on a network command must
  still stop when the network falls silent. A control word with REMOTE = 1
  takes network control (also out of `local_control`); only `local_control`
  (the keypad) disarms the watchdog.

Status word per state: RDY_ON in READY TO SWITCH ON / READY TO OPERATE /
OPERATION ENABLED / OFF1 ACTIVE; RDY_RUN in READY TO OPERATE / OPERATION
ENABLED; RDY_REF in OPERATION ENABLED only. OFF_2_STA mirrors the accepted
OFF2 bit; OFF_3_STA is 0 while OFF3 = 0 or an emergency stop runs. TRIPPED
with FAULT = first latched fault code. AT_SETPOINT: operation enabled and
|ACT - REF| <= AT_SETPOINT_BAND, REF taken after limiting (the ramp input).
ALARM: set by `set_alarm` (no built-in warning source).

Reference and limits
--------------------
REF is int16: rpm = REF * SPEED_SCALE / 20000. Its magnitude is limited to
MAX_SPEED (ABOVE_LIMIT = 1 while the written reference is being limited; REF
reads back what was written). The orbit drive (bidirectional) follows negative
references (backward whirl), crossing zero along DECEL then ACCEL. The spin
drive turns one direction only: a NEGATIVE reference is limited to 0 rpm (the
drive stays at / ramps down to standstill) and sets ABOVE_LIMIT ("reference
limited"); it is never reversed.

Parameters (addresses 100..105) are volatile and reset to the spec defaults
on construction. A write answers exception 03 and changes nothing while the
drive is producing torque (operation enabled, OFF1/OFF3 ramp stop, fault ramp
stop) or if a value is out of range:
SPEED_SCALE 1..30000, MAX_SPEED 0..30000, ACCEL_TIME and DECEL_TIME 1..18000,
COMM_LOSS_TIMEOUT 0..6000, AT_SETPOINT_BAND 0..3000.
Writing a read-only register (SW, ACT, TORQUE, FAULT) or any address outside
the map answers exception 02; a request touching any such address changes
nothing. A multi-register write is applied as one: REF2, REF, then CW.

Faults
------
2310, 4210, 7301: coast stop. 7510 (communication loss): ramp stop along
DECEL_TIME if the drive was under torque (a coasting drive keeps coasting; an
OFF3 emergency stop under way keeps its 10 x faster ramp).
Faults latch in order of occurrence. `inject_fault(code)` sets the cause and
trips; `clear_fault_cause()` removes the cause (the fault stays latched until
a RESET edge). The cause of 7510 is gone as soon as a valid request arrives.

Watchdog: armed while the drive is under network control (a control word with
REMOTE = 1 was accepted) and COMM_LOSS_TIMEOUT > 0; it trips 7510 when no
valid request addressed to this drive arrived for COMM_LOSS_TIMEOUT * 0.1 s of
wall time, also when the drive is stopped. Requests answered with an exception
count as valid (the link is alive); requests to another device id do not.

Coasting (torque off): the speed decays linearly at `coast_decel` rpm/s
(simulated). Torque (powered): TORQUE = 10000 * (alpha / a_nom
+ friction * speed / rated_rpm), a_nom = rated_rpm / starting_time, alpha the
current ramp acceleration (rpm/s, signed).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence

__all__ = [
    "DriveModel",
    "DriveModbusException",
    "ILLEGAL_FUNCTION",
    "ILLEGAL_ADDRESS",
    "ILLEGAL_VALUE",
    "CW", "REF", "REF2", "SW", "ACT", "TORQUE", "FAULT",
    "SPEED_SCALE", "MAX_SPEED", "ACCEL_TIME", "DECEL_TIME",
    "COMM_LOSS_TIMEOUT", "AT_SETPOINT_BAND",
    "PARAMETER_DEFAULTS", "PARAMETER_RANGES", "FAULT_REACTIONS",
]

# Modbus exception codes used by the map.
ILLEGAL_FUNCTION = 0x01
ILLEGAL_ADDRESS = 0x02
ILLEGAL_VALUE = 0x03

# Process data (0-based protocol addresses).
CW, REF, REF2, SW, ACT, TORQUE, FAULT = range(7)
# Parameters.
SPEED_SCALE, MAX_SPEED, ACCEL_TIME, DECEL_TIME, COMM_LOSS_TIMEOUT, AT_SETPOINT_BAND = range(100, 106)

PARAMETER_DEFAULTS = {
    SPEED_SCALE: 3000,
    MAX_SPEED: 2500,
    ACCEL_TIME: 50,
    DECEL_TIME: 50,
    COMM_LOSS_TIMEOUT: 10,
    AT_SETPOINT_BAND: 5,
}
PARAMETER_RANGES = {
    SPEED_SCALE: (1, 30000),
    MAX_SPEED: (0, 30000),
    ACCEL_TIME: (1, 18000),
    DECEL_TIME: (1, 18000),
    COMM_LOSS_TIMEOUT: (0, 6000),
    AT_SETPOINT_BAND: (0, 3000),
}
FAULT_REACTIONS = {2310: "coast", 4210: "coast", 7510: "ramp", 7301: "coast"}
COMM_LOSS_FAULT = 7510

REF_FULL_SCALE = 20000  # REF / ACT count for SPEED_SCALE rpm
EMERGENCY_FACTOR = 10.0  # OFF3 ramp is this much faster than DECEL_TIME

_READABLE = frozenset(range(0, 7)) | frozenset(PARAMETER_DEFAULTS)
_WRITABLE = frozenset((CW, REF, REF2)) | frozenset(PARAMETER_DEFAULTS)

# Control word bits.
CW_OFF1 = 1 << 0
CW_OFF2 = 1 << 1
CW_OFF3 = 1 << 2
CW_RUN = 1 << 3
CW_RAMP_OUT_ZERO = 1 << 4  # 0 = force ramp output to zero
CW_RAMP_HOLD = 1 << 5  # 0 = hold the ramp
CW_RAMP_IN_ZERO = 1 << 6  # 0 = force ramp input to zero
CW_RESET = 1 << 7
CW_REMOTE = 1 << 10

# Status word bits.
SW_RDY_ON = 1 << 0
SW_RDY_RUN = 1 << 1
SW_RDY_REF = 1 << 2
SW_TRIPPED = 1 << 3
SW_OFF_2_STA = 1 << 4
SW_OFF_3_STA = 1 << 5
SW_ALARM = 1 << 7
SW_AT_SETPOINT = 1 << 8
SW_REMOTE = 1 << 9
SW_ABOVE_LIMIT = 1 << 10

# States.
INHIBITED = "switch_on_inhibited"
READY = "ready_to_switch_on"
READY_RUN = "ready_to_operate"
ENABLED = "operation_enabled"
OFF1_ACTIVE = "off1_active"
OFF3_ACTIVE = "off3_active"
FAULTED = "fault"


class DriveModbusException(Exception):
    """A request the drive answers with a Modbus exception response.

    `code` is the Modbus exception code (2 = illegal data address,
    3 = illegal data value).
    """

    def __init__(self, code: int, message: str = "") -> None:
        super().__init__(message or f"Modbus exception {code:#04x}")
        self.code = code


def _int16(value: int) -> int:
    return value - 0x10000 if value >= 0x8000 else value


def _uint16(value: int) -> int:
    return value & 0xFFFF


def _clip16(value: float) -> int:
    return max(-32768, min(32767, int(round(value))))


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

        self._params = dict(PARAMETER_DEFAULTS)
        self._cw_reg = 0  # last written CW (reads back)
        self._cw = 0  # last accepted CW (REMOTE = 1)
        self._ref_reg = 0  # last written REF, int16
        self._ref = 0  # last accepted REF, int16
        self._ref2 = 0
        self._remote = False
        self._watchdog_armed = False  # armed by network control, disarmed only by the keypad
        self._local = False
        self._local_rpm = 0.0
        self._alarm = False

        self._state = INHIBITED
        self._speed = 0.0  # rpm, signed
        self._alpha = 0.0  # rpm/s, current ramp acceleration (powered)
        self._faults: list[int] = []  # latched, in order
        self._causes: set[int] = set()  # fault causes still present
        self._fault_ramp = False  # 7510 ramp stop in progress
        self._fault_ramp_factor = 1.0  # x DECEL rate (EMERGENCY_FACTOR if OFF3 was active)

        self._t = float(clock())
        self._w = float(wall_clock())
        self._last_request = self._w

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
        return self._faults[0] if self._faults else 0

    @property
    def faults(self) -> tuple[int, ...]:
        """All latched fault codes in order of occurrence."""
        return tuple(self._faults)

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
        expiry = self._watchdog_expiry()
        if expiry is not None and expiry <= w_now:
            if w_now > self._w:
                frac = min(1.0, max(0.0, (expiry - self._w) / (w_now - self._w)))
            else:
                frac = 1.0
            self._integrate_to(self._t + frac * (t_now - self._t))
            self._trip(COMM_LOSS_FAULT)
            self._causes.add(COMM_LOSS_FAULT)
        self._integrate_to(t_now)
        self._w = max(w_now, self._w)

    def note_request(self) -> None:
        """A valid request addressed to this drive arrived: feed the watchdog."""
        self.advance()
        self._last_request = self._w
        self._causes.discard(COMM_LOSS_FAULT)

    def read(self, address: int, count: int) -> list[int]:
        """Function code 03: `count` registers from `address` as uint16."""
        if count < 1:
            raise DriveModbusException(ILLEGAL_VALUE, "count must be >= 1")
        addresses = range(address, address + count)
        for a in addresses:
            if a not in _READABLE:
                raise DriveModbusException(ILLEGAL_ADDRESS, f"address {a} is not in the map")
        self.advance()
        return [_uint16(self._register(a)) for a in addresses]

    def write(self, address: int, values: Sequence[int]) -> None:
        """Function codes 06 / 16: write uint16 `values` from `address`, all or nothing."""
        values = [int(v) for v in values]
        if not values:
            raise DriveModbusException(ILLEGAL_VALUE, "nothing to write")
        for a in range(address, address + len(values)):
            if a not in _WRITABLE:
                kind = "read-only" if a in _READABLE else "not in the map"
                raise DriveModbusException(ILLEGAL_ADDRESS, f"address {a} is {kind}")
        for v in values:
            if not 0 <= v <= 0xFFFF:
                raise DriveModbusException(ILLEGAL_VALUE, f"value {v} is not 16 bit")
        self.advance()
        updates = {address + i: v for i, v in enumerate(values)}
        params = {a: v for a, v in updates.items() if a in PARAMETER_DEFAULTS}
        if params:
            if self._modulating():
                raise DriveModbusException(ILLEGAL_VALUE, "parameter write while running")
            for a, v in params.items():
                lo, hi = PARAMETER_RANGES[a]
                if not lo <= v <= hi:
                    raise DriveModbusException(
                        ILLEGAL_VALUE, f"parameter {a} = {v} outside {lo}..{hi}"
                    )
            self._params.update(params)
            if COMM_LOSS_TIMEOUT in params:
                self._last_request = self._w  # a new timeout starts counting now
        if REF2 in updates:
            self._ref2 = _int16(updates[REF2])
        if REF in updates:
            self._ref_reg = _int16(updates[REF])
            if self._remote:
                self._ref = self._ref_reg
        if CW in updates:
            self._write_cw(updates[CW])

    def inject_fault(self, code: int) -> None:
        """Trip with `code` (2310, 4210, 7301, 7510); its cause stays until cleared."""
        if code not in FAULT_REACTIONS:
            raise ValueError(f"unknown fault code {code}; known: {sorted(FAULT_REACTIONS)}")
        self.advance()
        self._causes.add(code)
        self._trip(code)

    def clear_fault_cause(self, code: int | None = None) -> None:
        """Remove the cause of fault `code` (all causes if None); a RESET edge still
        has to clear the latched fault."""
        if code is None:
            self._causes.clear()
        else:
            self._causes.discard(code)

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
        self._watchdog_armed = False
        limit = float(self._params[MAX_SPEED])
        self._local_rpm = math.copysign(min(abs(float(rpm)), limit), rpm)
        self._speed = self._local_rpm
        self._alpha = 0.0
        self._cw = CW_OFF2 | CW_OFF3 | CW_RAMP_OUT_ZERO | CW_RAMP_HOLD | CW_RAMP_IN_ZERO
        if rpm != 0:
            self._cw |= CW_OFF1 | CW_RUN
            self._state = ENABLED
        else:
            self._state = READY

    # ------------------------------------------------------------ registers
    def _register(self, address: int) -> int:
        if address == CW:
            return self._cw_reg
        if address == REF:
            return self._ref_reg
        if address == REF2:
            return self._ref2
        if address == SW:
            return self._status_word()
        if address == ACT:
            return _clip16(self._speed * REF_FULL_SCALE / self._params[SPEED_SCALE])
        if address == TORQUE:
            return _clip16(10000.0 * self.torque)
        if address == FAULT:
            return self.fault_code
        return self._params[address]

    def _status_word(self) -> int:
        s = self._state
        sw = 0
        if s in (READY, READY_RUN, ENABLED, OFF1_ACTIVE):
            sw |= SW_RDY_ON
        if s in (READY_RUN, ENABLED):
            sw |= SW_RDY_RUN
        if s == ENABLED:
            sw |= SW_RDY_REF
        if s == FAULTED:
            sw |= SW_TRIPPED
        if self._cw & CW_OFF2:
            sw |= SW_OFF_2_STA
        if self._cw & CW_OFF3 and s != OFF3_ACTIVE:
            sw |= SW_OFF_3_STA
        if self._alarm:
            sw |= SW_ALARM
        ref, limited = self._limited_reference()
        if s == ENABLED and abs(self._speed - ref) <= self._params[AT_SETPOINT_BAND]:
            sw |= SW_AT_SETPOINT
        if self._remote:
            sw |= SW_REMOTE
        if limited:
            sw |= SW_ABOVE_LIMIT
        return sw

    def _limited_reference(self) -> tuple[float, bool]:
        """(reference rpm after limiting, whether it was limited)."""
        if self._local:
            return self._local_rpm, False
        rpm = self._ref * self._params[SPEED_SCALE] / REF_FULL_SCALE
        limit = float(self._params[MAX_SPEED])
        if rpm < 0 and not self.bidirectional:
            return 0.0, True
        if abs(rpm) > limit:
            return math.copysign(limit, rpm), True
        return rpm, False

    # -------------------------------------------------------- state machine
    def _write_cw(self, value: int) -> None:
        self._cw_reg = value
        if not value & CW_REMOTE:
            self._remote = False  # stored, not acted on; the watchdog stays armed
            return
        if not self._watchdog_armed:
            self._watchdog_armed = True
            self._last_request = self._w  # arming starts a fresh timeout
        self._remote = True
        self._local = False
        self._ref = self._ref_reg
        old, self._cw = self._cw, value
        if value & CW_RESET and not old & CW_RESET:
            self._reset_faults()
        self._evaluate()

    def _reset_faults(self) -> None:
        if self._state != FAULTED:
            return
        self._faults = [f for f in self._faults if f in self._causes]
        if not self._faults:
            self._fault_ramp = False
            self._state = INHIBITED

    def _evaluate(self) -> None:
        """Apply the accepted control word to the state (until stable)."""
        cw = self._cw
        off1, off2, off3, run = (bool(cw & b) for b in (CW_OFF1, CW_OFF2, CW_OFF3, CW_RUN))
        for _ in range(4):
            s = self._state
            if s == FAULTED:
                return
            if not off2:
                new = INHIBITED
            elif not off3:
                new = OFF3_ACTIVE if s in (ENABLED, OFF1_ACTIVE, OFF3_ACTIVE) else INHIBITED
                if new == OFF3_ACTIVE and self._speed == 0.0:
                    new = INHIBITED
            elif s == INHIBITED:
                new = READY if not off1 else INHIBITED
            elif s == READY:
                new = READY_RUN if off1 else READY
            elif s == READY_RUN:
                new = READY if not off1 else (ENABLED if run else READY_RUN)
            elif s == ENABLED:
                new = (OFF1_ACTIVE if self._speed != 0.0 else READY) if not off1 else (
                    ENABLED if run else READY_RUN)
            elif s == OFF1_ACTIVE:
                new = (ENABLED if run else READY_RUN) if off1 else OFF1_ACTIVE
            else:  # OFF3_ACTIVE runs to standstill whatever OFF3 does meanwhile
                new = OFF3_ACTIVE
            if new == s:
                return
            self._state = new

    def _trip(self, code: int) -> None:
        was_powered = self._powered()
        if code not in self._faults:
            self._faults.append(code)
        if FAULT_REACTIONS[code] == "coast":
            self._fault_ramp = False
        elif self._state != FAULTED:
            self._fault_ramp = was_powered and self._speed != 0.0
            # an emergency stop already under way keeps its faster ramp
            self._fault_ramp_factor = EMERGENCY_FACTOR if self._state == OFF3_ACTIVE else 1.0
        self._state = FAULTED

    def _modulating(self) -> bool:
        """Producing torque: parameters are locked."""
        return self._state in (ENABLED, OFF1_ACTIVE, OFF3_ACTIVE) or (
            self._state == FAULTED and self._fault_ramp
        )

    def _powered(self) -> bool:
        return self._modulating()

    # ------------------------------------------------------------- dynamics
    def _rates(self) -> tuple[float, float]:
        scale = float(self._params[SPEED_SCALE])
        return (
            scale / (0.1 * self._params[ACCEL_TIME]),
            scale / (0.1 * self._params[DECEL_TIME]),
        )

    def _motion(self) -> tuple[float | None, float, float]:
        """(target rpm or None = hold, accel rate, decel rate) for the current state."""
        acc, dec = self._rates()
        s = self._state
        if s == ENABLED:
            cw = self._cw
            if not cw & CW_RAMP_OUT_ZERO:
                return 0.0, acc, EMERGENCY_FACTOR * dec
            if not cw & CW_RAMP_HOLD:
                return None, acc, dec
            if not cw & CW_RAMP_IN_ZERO:
                return 0.0, acc, dec
            if self._local:
                return self._local_rpm, acc, dec
            return self._limited_reference()[0], acc, dec
        if s == OFF1_ACTIVE:
            return 0.0, acc, dec
        if s == OFF3_ACTIVE:
            return 0.0, acc, EMERGENCY_FACTOR * dec
        if s == FAULTED and self._fault_ramp:
            return 0.0, acc, self._fault_ramp_factor * dec
        return 0.0, self._coast_decel, self._coast_decel  # torque off: coasting

    def _integrate_to(self, t_end: float) -> None:
        remaining = t_end - self._t
        self._t = max(self._t, t_end)
        for _ in range(16):  # a few phases at most: zero crossing, stop, state change
            target, up, down = self._motion()
            if target is None or self._speed == target:
                self._alpha = 0.0
                if self._standstill_transition():
                    continue
                return
            speed = self._speed
            toward_zero = (speed > 0 and target < speed) or (speed < 0 and target > speed)
            if toward_zero:
                rate = down
                stop = target if target * speed > 0 else 0.0
            else:
                rate = up
                stop = target
            self._alpha = math.copysign(rate, stop - speed)
            if remaining <= 0.0:
                return
            need = abs(stop - speed) / rate
            if need <= remaining + 1e-9:  # arrival (tolerating float round-off)
                self._speed = stop
                remaining = max(0.0, remaining - need)
                self._standstill_transition()
            else:
                self._speed = speed + math.copysign(rate * remaining, stop - speed)
                return

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

    def _watchdog_expiry(self) -> float | None:
        """Wall time at which the watchdog trips, None if disarmed."""
        timeout = self._params[COMM_LOSS_TIMEOUT]
        if not self._watchdog_armed or timeout == 0 or COMM_LOSS_FAULT in self._faults:
            return None
        return self._last_request + 0.1 * timeout
