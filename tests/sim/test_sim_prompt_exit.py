"""`orbitrig sim` and `python -m sim` end promptly on SIGTERM with clients on every server, and
close each connection (end of file, not a reset) without a traceback.

Before: 0.5-0.8 s at idle, 1.5-1.8 s with both cores busy (the CAN node's pyserial socket port sleeps
0.3 s on the event loop as it closes, then the interpreter tears its modules down); now 0.01-0.12 s
at idle, at most 0.21 s with both cores busy (tools/cpu-hog). The bound lies between.
"""

from __future__ import annotations

import json
import signal
import socket
import sys
import time

import pytest

from support.cli_helpers import orbitrig_cmd, reaped, started

#: wall s from SIGTERM to the process's end
EXIT_BOUND_S = 0.45


def _connect(url: str) -> socket.socket:
    host, port = url.split("//", 1)[1].rsplit(":", 1)
    return socket.create_connection((host, int(port)), timeout=5)


def _until_end_of_file(s: socket.socket) -> bytes:
    """What is left to read on ``s`` up to its end of file (a reset raises)."""
    s.settimeout(5)
    rest = b""
    while chunk := s.recv(65536):
        rest += chunk
    return rest


@pytest.mark.parametrize(
    "cmd",
    [
        orbitrig_cmd("sim", "--modbus-port", "0", "--adc-port", "0", "--can-port", "0"),
        [sys.executable, "-m", "sim", "--modbus-port", "0", "--adc-port", "0", "--can-hub", "0"],
    ],
    ids=["orbitrig-sim", "python-m-sim"],
)
def test_sigterm_ends_the_simulator_promptly_closing_every_connection(cmd):
    with reaped(started([*cmd, "--speedup", "5"], stdin=None)) as proc:
        ep = json.loads(proc.stdout.readline())
        with _connect(ep["control"]) as c:
            c.sendall(b'{"cmd": "local_control", "spin": 120.0, "orbit": -60.0}\n')
            assert json.loads(c.makefile().readline())["ok"]
        clients = {name: _connect(ep[name]) for name in ("modbus", "adc", "can", "control")}
        clients["control"].sendall(b'{"cmd": "state"}\n')
        assert clients["control"].recv(65536).startswith(b'{"ok": true')
        clients["modbus"].sendall(bytes.fromhex("000100000006010300000002"))  # read 2 registers of drive 1
        assert clients["modbus"].recv(64)[7] == 0x03
        assert clients["adc"].recv(65536)  # frames stream
        time.sleep(0.3)
        t0 = time.monotonic()
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=10) == 0
        took = time.monotonic() - t0
        for name, s in clients.items():
            with s:
                assert _until_end_of_file(s) is not None, name  # closed by the simulator: end of file
        err = proc.stderr.read()
    assert took < EXIT_BOUND_S, f"{took:.3f} s from SIGTERM to exit"
    assert "Traceback" not in err and "Exception" not in err, err
