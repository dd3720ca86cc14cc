"""The emulated drive's register map (docs/protocols/drive-modbus.md), the
simulator's own copy: addresses, parameter table, control / status word bits,
fault codes and the address / value checks of a Modbus request.

Pure data and checks, no state. `sim/drive_model.py` owns the drive that
answers through this map.

Process data (addresses 0..6): CW, REF, REF2 read / write; SW, ACT, TORQUE,
FAULT read-only. REF and ACT are int16: rpm = count * SPEED_SCALE / 20000.

Reference limits: the magnitude of REF is limited to MAX_SPEED (ABOVE_LIMIT = 1
while the written reference is being limited; REF reads back what was
written). The orbit drive (bidirectional) follows negative references
(backward whirl), crossing zero along DECEL then ACCEL. The spin drive turns
one direction only: a NEGATIVE reference is limited to 0 rpm (the drive stays
at / ramps down to standstill) and sets ABOVE_LIMIT ("reference limited"); it
is never reversed.

Parameters (addresses 100..105) are volatile and reset to the spec defaults
when a drive is built. Ranges: SPEED_SCALE 1..30000, MAX_SPEED 0..30000,
ACCEL_TIME and DECEL_TIME 1..18000 (0.1 s for SPEED_SCALE rpm),
COMM_LOSS_TIMEOUT 0..6000 (0.1 s, 0 = off), AT_SETPOINT_BAND 0..3000 (rpm).

Exception codes: 02 for a read / write touching an address outside the map or
a write to a read-only register (SW, ACT, TORQUE, FAULT); 03 for a bad count,
a value that is not 16 bit, a parameter out of range or written while the
drive produces torque. A request that fails a check changes nothing.

Faults and their reactions: 2310, 4210, 7301 coast stop; 7510 (communication
loss) ramp stop along DECEL_TIME.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

__all__ = [
    "DriveModbusException",
    "ILLEGAL_FUNCTION",
    "ILLEGAL_ADDRESS",
    "ILLEGAL_VALUE",
    "CW",
    "REF",
    "REF2",
    "SW",
    "ACT",
    "TORQUE",
    "FAULT",
    "SPEED_SCALE",
    "MAX_SPEED",
    "ACCEL_TIME",
    "DECEL_TIME",
    "COMM_LOSS_TIMEOUT",
    "AT_SETPOINT_BAND",
    "PARAMETER_DEFAULTS",
    "PARAMETER_RANGES",
    "FAULT_REACTIONS",
    "COMM_LOSS_FAULT",
    "REF_FULL_SCALE",
    "check_read",
    "check_write",
    "check_parameter_ranges",
    "limit_reference",
    "SPEED_ACCURACY",
    "turning_speed",
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


class DriveModbusException(Exception):
    """A request the drive answers with a Modbus exception response.

    `code` is the Modbus exception code (2 = illegal data address,
    3 = illegal data value).
    """

    def __init__(self, code: int, message: str = "") -> None:
        super().__init__(message or f"Modbus exception {code:#04x}")
        self.code = code


def int16(value: int) -> int:
    """A register's uint16 read as two's complement."""
    return value - 0x10000 if value >= 0x8000 else value


def uint16(value: int) -> int:
    """A signed value as the register's 16 bits."""
    return value & 0xFFFF


def clip16(value: float) -> int:
    """Round to the nearest count and saturate to int16."""
    return max(-32768, min(32767, int(round(value))))


def check_read(address: int, count: int) -> range:
    """The addresses of a function code 03 read; DriveModbusException if not in the map."""
    if count < 1:
        raise DriveModbusException(ILLEGAL_VALUE, "count must be >= 1")
    addresses = range(address, address + count)
    for a in addresses:
        if a not in _READABLE:
            raise DriveModbusException(ILLEGAL_ADDRESS, f"address {a} is not in the map")
    return addresses


def check_write(address: int, values: Sequence[int]) -> dict[int, int]:
    """{address: uint16} of a function code 06 / 16 write, all writable and 16 bit.

    Parameter ranges are checked separately (`check_parameter_ranges`), after
    the drive decided whether it accepts parameter writes at all.
    """
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
    return {address + i: v for i, v in enumerate(values)}


def check_parameter_ranges(params: Mapping[int, int]) -> None:
    """Exception 03 for the first parameter outside its range."""
    for a, v in params.items():
        lo, hi = PARAMETER_RANGES[a]
        if not lo <= v <= hi:
            raise DriveModbusException(ILLEGAL_VALUE, f"parameter {a} = {v} outside {lo}..{hi}")


def limit_reference(ref: int, speed_scale: int, max_speed: int, bidirectional: bool) -> tuple[float, bool]:
    """(reference rpm after limiting, whether it was limited) for the int16 REF `ref`."""
    rpm = ref * speed_scale / REF_FULL_SCALE
    limit = float(max_speed)
    if rpm < 0 and not bidirectional:
        return 0.0, True
    if abs(rpm) > limit:
        return math.copysign(limit, rpm), True
    return rpm, False


#: the largest steady speed error of a drive, as a fraction of its speed scale: 3 rpm of 3000 rpm,
#: inside the 5 rpm at-setpoint band at every speed (docs/simulator.md, "Speed error")
SPEED_ACCURACY = 0.001


def turning_speed(reference: float, speed_error: float, speed_scale: int, max_speed: int) -> float:
    """The rpm a drive turns at for its limited `reference` (rpm): off by `speed_error` (a fraction of
    it) by at most SPEED_ACCURACY x `speed_scale` either way, and never beyond `max_speed` (rpm)."""
    cap = SPEED_ACCURACY * speed_scale
    turned = reference + max(-cap, min(cap, reference * speed_error))
    return max(-float(max_speed), min(float(max_speed), turned))
