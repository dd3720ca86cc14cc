"""`orbitrig drives status` pointed at the wrong serial port on the first morning, over a real
serial line: a socat pty pair, the drives' end given in the URL, the test holding the other end
(as the cable's far side). A port that does not exist names it; one that carries another
device's bytes, or the drives' at another baud rate or parity (bytes come, none a valid RTU
answer), says so with the bytes counted, not only "no answer"; exit 2 within seconds."""

from __future__ import annotations

import contextlib
import errno
import os
import random
import shutil
import subprocess
import sys
import threading
import time

import pytest

from orbitrig.run.rig_answers import PORT_HINTS
from support.cli_helpers import orbitrig_here
from support.paths import ROOT
from support.serial_cable import serial_cable

pytestmark = pytest.mark.timeout(60)


def test_a_serial_port_that_does_not_exist_is_named(tmp_path):
    url = f"rtu://{tmp_path}/ttyUSB9?baud=19200"
    t0 = time.monotonic()
    p = orbitrig_here("drives", "status", "--modbus", url)
    assert p.returncode == 2 and p.stdout == ""
    assert f"error (link): cannot connect to {url}: " in p.stderr
    assert f"could not open port {tmp_path}/ttyUSB9" in p.stderr and "No such file or directory" in p.stderr
    assert 'OSError("' not in p.stderr  # was the wrapped error's repr
    assert p.stderr.splitlines()[-1] == "  " + PORT_HINTS[errno.ENOENT]  # not "is the Modbus server serving there?"
    assert time.monotonic() - t0 < 5


def test_a_serial_port_without_permission_is_named_with_its_group(tmp_path):
    """A real pty the user may not open (mode 000; root without CAP_DAC_OVERRIDE, as a user
    outside the dialout group): `drives status` and the sweep's check say what to do. A user
    other than root cannot open a mode 000 file anyway (nor drop capabilities: no setpriv)."""
    as_user: list[str] = []
    if os.geteuid() == 0:
        assert shutil.which("setpriv"), "setpriv: util-linux, installed by tools/run-tests"
        as_user = ["setpriv", "--bounding-set", "-dac_override,-dac_read_search"]
    with serial_cable(tmp_path) as (near, _far):
        os.chmod(os.path.realpath(near), 0)
        url = f"rtu://{near}?baud=19200"
        t0 = time.monotonic()
        p = subprocess.run(
            as_user + [sys.executable, "-m", "orbitrig", "drives", "status", "--modbus", url],
            capture_output=True, text=True, timeout=30, cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)},
        )  # fmt: skip
        took = time.monotonic() - t0
    assert p.returncode == 2 and p.stdout == "", p.stderr
    said = p.stderr.splitlines()
    assert said[0].startswith(f"orbitrig drives status: error (link): cannot connect to {url}: cannot open {near}: ")
    assert "Permission denied" in said[0]
    assert said[1:] == ["  " + PORT_HINTS[errno.EACCES]]
    assert "usermod -aG dialout" in said[1]
    assert took < 15, took  # a Python started and orbitrig imported, both cores busy


def test_a_serial_port_another_program_holds_is_said_so(tmp_path):
    """A second orbitrig (or a terminal program) holds the drives' port, opened exclusively."""
    import serial

    with serial_cable(tmp_path) as (near, _far):
        holder = serial.Serial(near, 19200, exclusive=True)
        try:
            p = orbitrig_here("drives", "status", "--modbus", f"rtu://{near}?baud=19200")
        finally:
            holder.close()
    assert p.returncode == 2
    assert "Could not exclusively lock port" in p.stderr
    assert p.stderr.splitlines()[-1] == "  " + PORT_HINTS[errno.EAGAIN]


def test_bytes_that_are_no_answer_are_said_so(tmp_path):
    """The far end sends what a device at another baud rate looks like, about 1900 bytes/s that
    make no CRC-valid frame: was 'no answer within 1 s' (the tests' lab: [drives] timeout_s 1.0),
    with the bytes dropped unsaid; the retry, which waits for a quiet line first, said the same."""
    stop = threading.Event()
    with serial_cable(tmp_path) as (near, far):
        noise = random.Random(7)

        def garble() -> None:
            while not stop.wait(0.01):
                with contextlib.suppress(OSError):
                    os.write(far, bytes(noise.randrange(256) for _ in range(19)))

        thread = threading.Thread(target=garble, daemon=True)
        thread.start()
        try:
            url = f"rtu://{near}?baud=19200"
            t0 = time.monotonic()
            p = orbitrig_here("drives", "status", "--modbus", url)
            took = time.monotonic() - t0
        finally:
            stop.set()
            thread.join(5)
    assert p.returncode == 2 and p.stdout == ""
    last = [line for line in p.stderr.splitlines() if "error (timeout)" in line]
    assert len(last) == 1, p.stderr
    assert (
        f"spin drive (id 1), registers 100..105 (SPEED_SCALE .. AT_SETPOINT_BAND): no answer within 1 s on {url}: "
        in last[0]
    )
    assert f"byte(s) came on {near}, no valid RTU frame (CRC) among them: is another device on this port" in last[0]
    assert "or are the drives at another baud rate or parity than 19200 baud, 8N1 (?baud= in the URL)?" in last[0]
    assert took < 8, took  # 1 s, the retry 1.1 s, both cores busy


def test_a_silent_port_is_no_answer_only(tmp_path):
    """Nothing on the far end (a cable to nowhere): no bytes, so no word of them."""
    with serial_cable(tmp_path) as (near, _far):
        url = f"rtu://{near}?baud=19200"
        p = orbitrig_here("drives", "status", "--modbus", url)
    assert p.returncode == 2
    assert (
        f"error (timeout): spin drive (id 1), registers 100..105 (SPEED_SCALE .. AT_SETPOINT_BAND): no answer within 1 s on {url}\n"
        in p.stderr
    )
    assert "byte(s) came" not in p.stderr
