"""The simulated drives' comm-loss watchdog judges when requests arrived, not when a starved
simulator got round to them (docs/simulator.md, "A starved simulator").

The drives are served from a loop in another thread (support.drives_testkit), their watchdog on
an AwakeClock as in the simulator process; a master in this
thread sends its requests on time, Modbus TCP or RTU over the pty, written from the spec. The
serving loop is blocked for three watchdog timeouts while the requests wait in the socket or the
pty: no trip (fault 7510), as a real drive would not trip. A master that falls silent while the
simulator runs still trips it.
"""

from __future__ import annotations

import os
import socket
import struct
import threading
import time

import pytest
from support.drives_testkit import SimDrives, served_from_a_thread

pytestmark = pytest.mark.timeout(60)

CW, FAULT, COMM_LOSS_TIMEOUT = 0, 6, 104  # the contract's registers, written out
CW_READY = 0x0476  # REMOTE = 1: network control, the watchdog armed
WATCHDOG = 10  # COMM_LOSS_TIMEOUT, 0.1 s: 1 s
PERIOD = 0.05  # s between two requests of the master (each drive every 0.1 s)


def _crc(frame: bytes) -> bytes:
    """Modbus RTU CRC-16 (poly 0xA001 reflected, init 0xFFFF), low byte first."""
    crc = 0xFFFF
    for byte in frame:
        crc ^= byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
    return struct.pack("<H", crc)


class Master:
    """Reads FAULT of drive 1 then 2, one request every PERIOD s, never waiting for an answer
    (a master times out and polls on); the answers are parsed at the end."""

    def __init__(self, kind: str, sim: SimDrives) -> None:
        self.kind, self.sent, self.rx = kind, 0, bytearray()
        if kind == "tcp":
            self.sock = socket.create_connection(("127.0.0.1", sim.endpoint.port or 0), timeout=5)
        else:
            self.fd = os.open(sim.endpoint.path or "", os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)

    def send(self) -> None:
        dev = 1 + self.sent % 2
        pdu = struct.pack(">BHH", 3, FAULT, 1)
        if self.kind == "tcp":
            self.sock.sendall(struct.pack(">HHHB", self.sent, 0, len(pdu) + 1, dev) + pdu)
        else:
            frame = bytes([dev]) + pdu
            os.write(self.fd, frame + _crc(frame))
        self.sent += 1

    def poll_for(self, seconds: float) -> None:
        t_end = time.monotonic() + seconds
        while time.monotonic() < t_end:
            self.send()
            time.sleep(PERIOD)

    def last_faults(self, answers: int) -> dict[int, int]:
        """FAULT of each drive in its last answer, once `answers` answers arrived (10 s at most)."""
        size = 11 if self.kind == "tcp" else 7  # MBAP 7 + fc, count, word; id, fc, count, word, CRC
        t_end = time.monotonic() + 10.0
        while len(self.rx) < answers * size and time.monotonic() < t_end:
            self._receive()
        faults = {}
        for k in range(len(self.rx) // size):
            a = bytes(self.rx[k * size : (k + 1) * size])
            dev, word = (a[6], a[9:11]) if self.kind == "tcp" else (a[0], a[3:5])
            faults[dev] = struct.unpack(">H", word)[0]
        return faults

    def _receive(self) -> None:
        try:
            if self.kind == "tcp":
                self.sock.settimeout(0.1)
                self.rx += self.sock.recv(4096)
            else:
                self.rx += os.read(self.fd, 4096)
        except (TimeoutError, BlockingIOError):
            time.sleep(0.01)

    def close(self) -> None:
        if self.kind == "tcp":
            self.sock.close()
        else:
            os.close(self.fd)


def _armed(sim: SimDrives) -> None:
    """Both drives under network control with a 1 s watchdog."""
    for model in sim.models.values():
        sim.in_loop(model.write, COMM_LOSS_TIMEOUT, [WATCHDOG])
        sim.in_loop(model.write, CW, [CW_READY])


@pytest.mark.parametrize("kind", ["tcp", "rtu"])
def test_requests_on_time_to_a_blocked_simulator_do_not_trip_it(kind):
    with served_from_a_thread(kind, speedup=5.0, awake=True) as sim:
        _armed(sim)
        master = Master(kind, sim)
        try:
            master.poll_for(0.3)
            assert sim.loop is not None
            blocked = threading.Event()
            sim.loop.call_soon_threadsafe(lambda: (blocked.set(), time.sleep(3.0)))  # 3 watchdog timeouts
            assert blocked.wait(10)
            master.poll_for(3.5)  # on time all along; the answers come once the loop runs again
            faults = master.last_faults(master.sent)
        finally:
            master.close()
        assert faults == {1: 0, 2: 0}
        assert all(m.fault_code == 0 and m.awake is not None and m.awake.stalled > 2.5 for m in sim.models.values())


@pytest.mark.parametrize("kind", ["tcp", "rtu"])
def test_a_master_that_falls_silent_trips_the_watchdog(kind):
    """Silent for 2 watchdog timeouts while the simulator runs: its next request finds 7510."""
    with served_from_a_thread(kind, speedup=5.0, awake=True) as sim:
        _armed(sim)
        master = Master(kind, sim)
        try:
            master.poll_for(0.5)
            assert master.last_faults(master.sent) == {1: 0, 2: 0}
            time.sleep(2.0)  # silent; the loop serving the drives runs (and ticks their clocks)
            master.send()
            master.send()
            faults = master.last_faults(master.sent)
        finally:
            master.close()
        assert faults == {1: 7510, 2: 7510}
