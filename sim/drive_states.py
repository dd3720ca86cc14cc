"""The emulated drive's state machine (common drive profile, control word /
status word) as pure functions: the state a control word leads to, the status
word of a state, the ramp each state drives the speed along, and one phase of
that ramp.

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
  DECEL_TIME (OFF3 ACTIVE, OFF_3_STA = 0), then SWITCH-ON INHIBITED; a word
  releasing OFF3 meanwhile changes nothing, unless the drive model's
  `off1_yields` is set: a ramp stop word (OFF1 = 0) then resumes the ramp stop.
- RUN = 0 while enabled: pulses inhibited, the spindle coasts (READY TO
  OPERATE); RUN = 1 again restarts from the current (coasting) speed.
- RAMP bits 4..6 (all 1 in normal operation): bit 4 = 0 forces the ramp
  output to zero (stop at the emergency rate), bit 5 = 0 holds the ramp (speed
  frozen), bit 6 = 0 forces the ramp input to zero (stop along DECEL_TIME).
- RESET (bit 7) 0 -> 1 edge: clears every latched fault whose cause is gone;
  when none is left the drive goes to SWITCH-ON INHIBITED and, since the reset
  word 0x04F6 has OFF1 = 0, straight on to READY TO SWITCH ON.

Status word per state: RDY_ON in READY TO SWITCH ON / READY TO OPERATE /
OPERATION ENABLED / OFF1 ACTIVE; RDY_RUN in READY TO OPERATE / OPERATION
ENABLED; RDY_REF in OPERATION ENABLED only. OFF_2_STA mirrors the accepted
OFF2 bit; OFF_3_STA is 0 while OFF3 = 0 or an emergency stop runs. TRIPPED
with FAULT = first latched fault code. AT_SETPOINT: operation enabled and
|ACT - REF| <= AT_SETPOINT_BAND, REF as written (not the limited ramp input):
a reference clamped at MAX_SPEED (ABOVE_LIMIT) is never reached, so AT_SETPOINT
stays 0 unless the band covers the difference; under local control the keypad
speed stands in for REF.
ALARM: raised by the drive's `set_alarm` (no built-in warning source).
"""

from __future__ import annotations

import math

from .drive_registers import (
    CW_OFF1,
    CW_OFF2,
    CW_OFF3,
    CW_RAMP_HOLD,
    CW_RAMP_IN_ZERO,
    CW_RAMP_OUT_ZERO,
    CW_RUN,
    SW_ABOVE_LIMIT,
    SW_ALARM,
    SW_AT_SETPOINT,
    SW_OFF_2_STA,
    SW_OFF_3_STA,
    SW_RDY_ON,
    SW_RDY_REF,
    SW_RDY_RUN,
    SW_REMOTE,
    SW_TRIPPED,
)

# States.
INHIBITED = "switch_on_inhibited"
READY = "ready_to_switch_on"
READY_RUN = "ready_to_operate"
ENABLED = "operation_enabled"
OFF1_ACTIVE = "off1_active"
OFF3_ACTIVE = "off3_active"
FAULTED = "fault"

EMERGENCY_FACTOR = 10.0  # OFF3 ramp is this much faster than DECEL_TIME


def settle(state: str, cw: int, speed: float, *, off1_yields: bool = False) -> str:
    """The state an accepted control word `cw` leads to from `state`, applied until
    stable; `speed` (rpm) decides whether a stop has anything left to ramp down.
    `off1_yields`: a ramp stop word (OFF3 = 1, OFF1 = 0) during the emergency ramp turns it
    into the ten times slower ramp stop (OFF1 ACTIVE), the worst a drive may do there."""
    off1, off2, off3, run = (bool(cw & b) for b in (CW_OFF1, CW_OFF2, CW_OFF3, CW_RUN))
    for _ in range(4):
        if state == FAULTED:
            return state
        if not off2:
            new = INHIBITED
        elif not off3:
            new = OFF3_ACTIVE if state in (ENABLED, OFF1_ACTIVE, OFF3_ACTIVE) else INHIBITED
            if new == OFF3_ACTIVE and speed == 0.0:
                new = INHIBITED
        elif state == INHIBITED:
            new = READY if not off1 else INHIBITED
        elif state == READY:
            new = READY_RUN if off1 else READY
        elif state == READY_RUN:
            new = READY if not off1 else (ENABLED if run else READY_RUN)
        elif state == ENABLED:
            new = (OFF1_ACTIVE if speed != 0.0 else READY) if not off1 else (ENABLED if run else READY_RUN)
        elif state == OFF1_ACTIVE:
            new = (ENABLED if run else READY_RUN) if off1 else OFF1_ACTIVE
        else:  # OFF3_ACTIVE runs to standstill whatever OFF3 does meanwhile (unless `off1_yields`)
            new = OFF1_ACTIVE if off1_yields and not off1 else OFF3_ACTIVE
        if new == state:
            return state
        state = new
    return state


def modulating(state: str, fault_ramp: bool) -> bool:
    """Producing torque (parameters locked): enabled, a ramp stop, or a fault ramp stop."""
    return state in (ENABLED, OFF1_ACTIVE, OFF3_ACTIVE) or (state == FAULTED and fault_ramp)


def status_word(state: str, cw: int, *, alarm: bool, at_setpoint: bool, remote: bool, above_limit: bool) -> int:
    """The status word of `state` under the accepted control word `cw`.

    `at_setpoint` counts only in OPERATION ENABLED.
    """
    sw = 0
    if state in (READY, READY_RUN, ENABLED, OFF1_ACTIVE):
        sw |= SW_RDY_ON
    if state in (READY_RUN, ENABLED):
        sw |= SW_RDY_RUN
    if state == ENABLED:
        sw |= SW_RDY_REF
    if state == FAULTED:
        sw |= SW_TRIPPED
    if cw & CW_OFF2:
        sw |= SW_OFF_2_STA
    if cw & CW_OFF3 and state != OFF3_ACTIVE:
        sw |= SW_OFF_3_STA
    if alarm:
        sw |= SW_ALARM
    if state == ENABLED and at_setpoint:
        sw |= SW_AT_SETPOINT
    if remote:
        sw |= SW_REMOTE
    if above_limit:
        sw |= SW_ABOVE_LIMIT
    return sw


def motion(
    state: str,
    cw: int,
    *,
    reference: float,
    accel: float,
    decel: float,
    coast_decel: float,
    fault_ramp: bool,
    fault_ramp_factor: float,
) -> tuple[float | None, float, float]:
    """(target rpm or None = hold, accel rate, decel rate) in `state`, rates in rpm/s.

    `reference` is the ramp input after limiting, `accel` / `decel` the
    ACCEL_TIME / DECEL_TIME rates; a drive with torque off coasts at `coast_decel`.
    """
    if state == ENABLED:
        if not cw & CW_RAMP_OUT_ZERO:
            return 0.0, accel, EMERGENCY_FACTOR * decel
        if not cw & CW_RAMP_HOLD:
            return None, accel, decel
        if not cw & CW_RAMP_IN_ZERO:
            return 0.0, accel, decel
        return reference, accel, decel
    if state == OFF1_ACTIVE:
        return 0.0, accel, decel
    if state == OFF3_ACTIVE:
        return 0.0, accel, EMERGENCY_FACTOR * decel
    if state == FAULTED and fault_ramp:
        return 0.0, accel, fault_ramp_factor * decel
    return 0.0, coast_decel, coast_decel  # torque off: coasting


def ramp_phase(
    speed: float, target: float, accel: float, decel: float, remaining: float
) -> tuple[float, float, float | None]:
    """Run the ramp from `speed` toward `target` (rpm, signed) for `remaining` s.

    Away from zero the speed changes at `accel`, toward zero at `decel` (rpm/s);
    a target across zero is one phase to standstill first. Returns (speed rpm,
    ramp acceleration rpm/s signed, seconds left after reaching the phase's end,
    or None while still on the way).
    """
    toward_zero = (speed > 0 and target < speed) or (speed < 0 and target > speed)
    if toward_zero:
        rate = decel
        stop = target if target * speed > 0 else 0.0
    else:
        rate = accel
        stop = target
    alpha = math.copysign(rate, stop - speed)
    if remaining <= 0.0:
        return speed, alpha, None
    need = abs(stop - speed) / rate
    if need <= remaining + 1e-9:  # arrival (tolerating float round-off)
        return stop, alpha, max(0.0, remaining - need)
    return speed + math.copysign(rate * remaining, stop - speed), alpha, None
