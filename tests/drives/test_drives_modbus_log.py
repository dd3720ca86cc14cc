"""pymodbus' own records of a late answer (an error and a hex dump of its last frames) go to the
run's log as `debug pymodbus` lines, and nothing of them reaches the terminal (stderr); of a
burst of them the log keeps the first few and a count."""

from __future__ import annotations

import logging
import re

import pytest
from support.drives_testkit import RPM, open_rig

from drives.limits import DriveLimits
from orbitrig.run.modbus_log import BURST_HEAD, RECORD_CHARS, pymodbus_into

pytestmark = pytest.mark.timeout(30)


class RunLog:
    """A run log's lines (the interface of RunStore.log)."""

    def __init__(self):
        self.lines: list[str] = []

    def log(self, message: str) -> None:
        self.lines.append(message)


async def test_pymodbus_records_go_to_the_run_log_not_the_terminal(tcp_sim, capfd):
    logging.getLogger("pymodbus").setLevel(logging.NOTSET)  # as in a sweep (the conftest quiets it)
    run_log = RunLog()
    with pymodbus_into(run_log):
        async with open_rig(tcp_sim, DriveLimits(2400 * RPM, 2400 * RPM), comm_loss_timeout=5.0) as r:
            tcp_sim.endpoint.drop_next(1)
            await r.spin.read_status(retries=1)  # one late answer: pymodbus logs it, the retry answers
    err = capfd.readouterr().err
    assert run_log.lines and all(line.startswith("debug pymodbus ") for line in run_log.lines), run_log.lines
    assert any("0x" in line for line in run_log.lines)  # its hex dump is kept for whoever debugs the link
    assert "pymodbus" not in err and "0x" not in err, err


async def test_a_burst_of_timeouts_keeps_its_first_records_and_a_count(tcp_sim):
    """Ten late answers in a row (one burst): run.log keeps the first BURST_HEAD records, each
    at most RECORD_CHARS long, and one line counting the rest; the next run starts afresh."""
    logging.getLogger("pymodbus").setLevel(logging.NOTSET)
    burst, after = RunLog(), RunLog()
    async with open_rig(tcp_sim, DriveLimits(2400 * RPM, 2400 * RPM), comm_loss_timeout=5.0) as r:
        with pymodbus_into(burst):
            tcp_sim.endpoint.drop_next(10)
            await r.spin.read_status(retries=10)  # ten timeouts within 1.1 s, then an answer
        with pymodbus_into(after):
            tcp_sim.endpoint.drop_next(1)
            await r.spin.read_status(retries=1)
    head, last = burst.lines[:-1], burst.lines[-1]
    assert len(head) == BURST_HEAD, burst.lines
    assert all(line.startswith("debug pymodbus ") and len(line) < RECORD_CHARS + 100 for line in head)
    m = re.fullmatch(r"debug pymodbus (\d+) more records of this burst left out \((\d+) lines\)", last)
    assert m and BURST_HEAD + int(m[1]) >= 10 and int(m[2]) >= int(m[1]), burst.lines  # a record per timeout
    assert 1 <= len(after.lines) <= BURST_HEAD and "left out" not in after.lines[-1], after.lines
