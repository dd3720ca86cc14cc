"""Helpers of the drive-emulation tests (independent of sim/: bits from the spec)."""

from __future__ import annotations

import json
import socket
import time

# Control words of docs/protocols/drive-modbus.md.
READY = 0x0476
RUN = 0x047F
RAMP_STOP = 0x047E
EMERGENCY = 0x047B
RESET = 0x04F6
COAST = 0x0475  # OFF2 = 0

# Status word bits.
RDY_ON = 1 << 0
RDY_RUN = 1 << 1
RDY_REF = 1 << 2
TRIPPED = 1 << 3
OFF_2_STA = 1 << 4
OFF_3_STA = 1 << 5
ALARM = 1 << 7
AT_SETPOINT = 1 << 8
REMOTE = 1 << 9
ABOVE_LIMIT = 1 << 10

# Register addresses.
CW, REF, REF2, SW, ACT, TORQUE, FAULT = range(7)
SPEED_SCALE, MAX_SPEED, ACCEL_TIME, DECEL_TIME, COMM_LOSS_TIMEOUT, AT_SETPOINT_BAND = range(100, 106)


def u16(value: int) -> int:
    return value & 0xFFFF


def s16(value: int) -> int:
    return value - 0x10000 if value >= 0x8000 else value


def ref_counts(rpm: float, scale: float = 3000.0) -> int:
    """REF register value (uint16 on the wire) for a speed in rpm."""
    return u16(round(rpm * 20000 / scale))


class FakeClocks:
    """Simulated and wall clocks under the test's control."""

    def __init__(self) -> None:
        self.sim = 0.0
        self.wall = 0.0

    def sim_clock(self) -> float:
        return self.sim

    def wall_clock(self) -> float:
        return self.wall

    def tick(self, seconds: float, *, wall: float = 0.0) -> None:
        """Advance simulated time by `seconds` and wall time by `wall` seconds.

        Wall time stands still unless asked for, so only the watchdog tests
        see the communication-loss timeout run.
        """
        self.sim += seconds
        self.wall += wall


class SpeedupClock:
    """Simulated seconds = wall seconds * speedup, for the server tests."""

    def __init__(self, speedup: float) -> None:
        self.speedup = speedup
        self.t0 = time.monotonic()

    def __call__(self) -> float:
        return (time.monotonic() - self.t0) * self.speedup


def sim_control(endpoints: dict, **request) -> dict:
    """One request to the simulator's control API (docs/protocols/sim-control.md) at
    ``endpoints["control"]`` (tcp://HOST:PORT): its reply, which must be ok."""
    host, port = endpoints["control"].removeprefix("tcp://").split(":")
    with socket.create_connection((host, int(port)), timeout=5) as s:
        s.sendall((json.dumps(request) + "\n").encode())
        reply = json.loads(s.makefile().readline())
    assert reply["ok"], reply
    return reply
