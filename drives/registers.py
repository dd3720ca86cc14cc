"""The drives' Modbus register map (docs/protocols/drive-modbus.md), pure.

Addresses are the 0-based protocol addresses pymodbus takes. Speeds in the
registers are int16 two's complement scaled so that REF = +/-20000 means
+/- SPEED_SCALE rpm; this module converts between raw words and rpm. The
conversion to rad/s happens in `drives.drive` (rpm lives only in registers and
on the command line).
"""

from __future__ import annotations

import enum
import math

#: the Modbus device ids a drive may answer at (0 is broadcast, 248..255 reserved)
MIN_DEVICE_ID, MAX_DEVICE_ID = 1, 247

# Process data
CW = 0
REF = 1
REF2 = 2
SW = 3
ACT = 4
TORQUE = 5
FAULT = 6
PROCESS_DATA = (CW, 7)  # first address, count: CW..FAULT in one read

# Parameters (volatile; writable only while the drive is not running)
SPEED_SCALE = 100
MAX_SPEED = 101
ACCEL_TIME = 102
DECEL_TIME = 103
COMM_LOSS_TIMEOUT = 104
AT_SETPOINT_BAND = 105
PARAMETERS = (SPEED_SCALE, 6)  # first address, count: SPEED_SCALE..AT_SETPOINT_BAND

REGISTER_NAMES: dict[int, str] = {
    CW: "CW",
    REF: "REF",
    REF2: "REF2",
    SW: "SW",
    ACT: "ACT",
    TORQUE: "TORQUE",
    FAULT: "FAULT",
    SPEED_SCALE: "SPEED_SCALE",
    MAX_SPEED: "MAX_SPEED",
    ACCEL_TIME: "ACCEL_TIME",
    DECEL_TIME: "DECEL_TIME",
    COMM_LOSS_TIMEOUT: "COMM_LOSS_TIMEOUT",
    AT_SETPOINT_BAND: "AT_SETPOINT_BAND",
}

REF_FULL_SCALE = 20000  # raw REF/ACT value that means SPEED_SCALE rpm
TORQUE_FULL_SCALE = 10000  # raw TORQUE value that means 100 % of nominal
TIME_UNIT = 0.1  # s per count of ACCEL_TIME, DECEL_TIME, COMM_LOSS_TIMEOUT

#: SPEED_SCALE and MAX_SPEED (rpm) as a drive holds them after power-up (the contract's defaults:
#: the parameters are volatile, and nothing of ours writes these two)
SPEED_SCALE_DEFAULT_RPM = 3000
MAX_SPEED_DEFAULT_RPM = 2500


class CWBit(enum.IntFlag):
    """Control word bits."""

    OFF1 = 1 << 0  # 1 = on; 0 = ramp stop
    OFF2 = 1 << 1  # 0 = coast stop
    OFF3 = 1 << 2  # 0 = emergency (fastest ramp) stop
    RUN = 1 << 3  # operation enabled
    RAMP = 0b111 << 4  # ramp function generator enabled (all three bits)
    RESET = 1 << 7  # 0 -> 1 edge acknowledges a fault
    REMOTE = 1 << 10  # network control


class SWBit(enum.IntFlag):
    """Status word bits."""

    RDY_ON = 1 << 0
    RDY_RUN = 1 << 1
    RDY_REF = 1 << 2
    TRIPPED = 1 << 3
    OFF_2_STA = 1 << 4  # 0 = coast stop active
    OFF_3_STA = 1 << 5  # 0 = emergency stop active
    ALARM = 1 << 7
    AT_SETPOINT = 1 << 8
    REMOTE = 1 << 9
    ABOVE_LIMIT = 1 << 10


_BASE = CWBit.REMOTE | CWBit.RAMP | CWBit.OFF2 | CWBit.OFF3
CW_READY = int(_BASE)  # 0x0476: ready to switch on (also: ramp stop from standstill)
CW_RUN = int(_BASE | CWBit.OFF1 | CWBit.RUN)  # 0x047F
CW_RAMP_STOP = int(_BASE | CWBit.RUN)  # 0x047E: OFF1 = 0, ramp along DECEL_TIME
CW_EMERGENCY_STOP = int((_BASE & ~CWBit.OFF3) | CWBit.OFF1 | CWBit.RUN)  # 0x047B: OFF3 = 0
CW_RESET = int(_BASE | CWBit.RESET)  # 0x04F6, followed by CW_READY

FAULT_NAMES: dict[int, str] = {
    2310: "overcurrent",
    4210: "overtemperature",
    7510: "communication loss",
    7301: "speed feedback lost",
}
FAULT_COMM_LOSS = 7510

EXCEPTION_NAMES: dict[int, str] = {
    1: "illegal function",
    2: "illegal data address",
    3: "illegal data value",
    4: "server device failure",
    6: "server device busy",
    10: "gateway path unavailable",
    11: "gateway target device failed to respond",
}


def register_name(address: int) -> str:
    """`'REF (1)'`: the register's spec name and protocol address."""
    return f"{REGISTER_NAMES.get(address, 'unknown register')} ({address})"


def registers_name(address: int, count: int = 1) -> str:
    """`'register REF (1)'` for one register; for a range, which the client cannot narrow
    down to the register at fault, `'registers 105..106 (AT_SETPOINT_BAND .. ?)'`."""
    if count <= 1:
        return f"register {register_name(address)}"
    last = address + count - 1
    return f"registers {address}..{last} ({REGISTER_NAMES.get(address, '?')} .. {REGISTER_NAMES.get(last, '?')})"


def fault_name(code: int) -> str:
    """The spec's meaning of a FAULT code (`'none'` for 0)."""
    if code == 0:
        return "none"
    return FAULT_NAMES.get(code, "unknown fault")


def to_word(value: int) -> int:
    """A signed int16 as the unsigned 16-bit register word Modbus carries."""
    if not -0x8000 <= value <= 0x7FFF:
        raise ValueError(f"{value} does not fit a signed 16-bit register")
    return value & 0xFFFF


def from_word(word: int) -> int:
    """The signed int16 value of a 16-bit register word."""
    word &= 0xFFFF
    return word - 0x10000 if word & 0x8000 else word


def rpm_to_ref(rpm: float, speed_scale: float) -> int:
    """Raw signed REF for a speed in rpm (REF_FULL_SCALE = speed_scale rpm), rounded.

    Raises ValueError when the value does not fit int16 or is not finite.
    """
    if not math.isfinite(rpm):
        raise ValueError(f"speed {rpm} rpm is not finite")
    if speed_scale <= 0:
        raise ValueError(f"SPEED_SCALE {speed_scale} rpm is not positive")
    raw = round(rpm * REF_FULL_SCALE / speed_scale)
    to_word(raw)  # range check
    return raw


def ref_to_rpm(raw: int, speed_scale: float) -> float:
    """Speed in rpm of a raw signed REF/ACT value."""
    return raw * speed_scale / REF_FULL_SCALE


#: the fastest speed (rpm, either direction) a REF commands on the drive as the contract gives it:
#: MAX_SPEED (a larger reference is clamped, and refused by drives.drive.Drive.reference_for), within
#: what an int16 REF reaches at SPEED_SCALE (4915 rpm). A configured speed limit above it is refused
#: when the configuration is read (orbitrig.config's [drives] max_spin_rpm, max_orbit_rpm).
MAX_COMMANDABLE_RPM = min(MAX_SPEED_DEFAULT_RPM, ref_to_rpm(0x7FFF, SPEED_SCALE_DEFAULT_RPM))


def counts(value: float, unit: float) -> int:
    """A parameter's register counts for `value` in units of `unit` (TIME_UNIT s, 1 rpm), rounded as
    drives.drive.Drive.configure writes it: COMM_LOSS_TIMEOUT 0.04 s is 0 counts, its watchdog off."""
    return round(value / unit)


def in_emergency_ramp(sw: int, act_raw: int) -> bool:
    """Turning in its emergency stop: SW OFF_3_STA 0 (emergency stop active) and a nonzero raw ACT.
    A ramp stop word (OFF1) then would turn that ramp into the ten times slower ramp stop."""
    return not sw & SWBit.OFF_3_STA and act_raw != 0


def state_name(sw: int) -> str:
    """The drive-profile state the status word shows, in words."""
    sw = SWBit(sw & 0xFFFF)
    if SWBit.TRIPPED in sw:
        return "fault"
    if SWBit.RDY_REF in sw:
        return "running"
    if SWBit.RDY_RUN in sw:
        return "ready to operate"
    if SWBit.RDY_ON in sw:
        return "ready to switch on"
    if SWBit.OFF_3_STA not in sw and SWBit.OFF_2_STA in sw:
        return "emergency stop"
    return "switch-on inhibited"
