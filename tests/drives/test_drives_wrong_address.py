"""`orbitrig drives` pointed at a wrong address, as on the first morning on the rig: each failure
names the host:port, and why the connect failed (refused: tests/cli/test_cli_no_rig.py), or the
device id and registers of a refused request with the host:port; exit 2, nothing sent.
Run in the test's process (support.cli_helpers.orbitrig_here), the drives from another thread."""

from __future__ import annotations

import re
import time

import pytest

from orbitrig.cli.drives_stop import HINT_CONNECT
from support.cli_helpers import orbitrig_here
from support.drives_testkit import CW_RAMP_STOP
from support.ports import blackholed_port

pytestmark = pytest.mark.timeout(60)

HINT = "  " + HINT_CONNECT  # the error's second line, indented


def test_a_host_that_does_not_answer_the_connect_is_said_so():
    """Was `cannot connect to tcp://127.0.0.1:P: TimeoutError()`."""
    with blackholed_port() as port:
        url = f"tcp://127.0.0.1:{port}"
        t0 = time.monotonic()
        p = orbitrig_here("drives", "status", "--modbus", url)
        took = time.monotonic() - t0
    assert p.returncode == 2 and p.stdout == ""
    said = p.stderr.splitlines()
    assert len(said) == 2 and said[1] == HINT, p.stderr
    within = re.fullmatch(
        rf"orbitrig drives status: error \(link\): cannot connect to {re.escape(url)}: no answer to the "
        r"connection within ([\d.]+) s \(a wrong or unreachable host, or a firewall dropping the port\)",
        said[0],
    )
    assert within, p.stderr
    assert float(within[1]) == pytest.approx(1.5)  # the lab's [drives] timeout_s 1.0 + 0.5 s to connect
    assert took < 10  # that per connect, not a TCP retry's minutes


def test_a_host_name_not_found_is_said_so():
    """Was `cannot connect to tcp://no-such-drive.invalid:502` without a reason."""
    url = "tcp://no-such-drive.invalid:502"  # .invalid: never resolves (RFC 2606)
    p = orbitrig_here("drives", "status", "--modbus", url)
    assert p.returncode == 2
    assert f"orbitrig drives status: error (link): cannot connect to {url}: host name not found (" in p.stderr


def test_a_device_id_the_gateway_does_not_have_names_id_registers_and_address(threaded_tcp_sim):
    """--spin-id 5 where the drives are 1 and 2: the simulator's TCP server answers as a gateway,
    exception 11; was the same without the host:port, and without a word of the device id."""
    url = threaded_tcp_sim.url
    p = orbitrig_here("drives", "status", "--modbus", url, "--spin-id", "5")
    assert p.returncode == 2 and p.stdout == ""
    assert (
        "orbitrig drives status: error (refused): spin drive (id 5), registers 100..105 (SPEED_SCALE .. "
        f"AT_SETPOINT_BAND): request FC03 refused on {url}: Modbus exception 11 (gateway target device "
        "failed to respond)"
    ) in p.stderr
    assert p.stderr.splitlines()[-1] == (
        "  is that the drive's device id? set [drives] spin_id and orbit_id in the rig config or pass --spin-id, "
        "--orbit-id"
    ), p.stderr
    assert threaded_tcp_sim.regs(1)["CW"] == threaded_tcp_sim.regs(2)["CW"] == 0  # nothing written to the drives


@pytest.mark.parametrize(
    ("flag", "wrong", "other", "other_id"), [("--spin-id", "spin", "orbit", 2), ("--orbit-id", "orbit", "spin", 1)]
)
def test_a_run_at_a_device_id_the_gateway_does_not_have_started_nothing_there(
    threaded_tcp_sim, flag, wrong, other, other_id
):
    """`drives run --spin-id 5` where the drives are 1 and 2: nothing was ever started at id 5, so
    no stop is needed there; the other drive still gets the stop. Was `stop NOT delivered (...);
    ... use the rig's emergency stop`, as if a drive might be turning unstoppable."""
    url = threaded_tcp_sim.url
    p = orbitrig_here("drives", "run", "--modbus", url, flag, "5", "--spin", "1000", "--orbit", "0", "--timeout", "5")
    assert p.returncode == 2 and p.stdout == ""
    said = p.stderr.splitlines()
    assert said[0].startswith(f"orbitrig drives run: error (refused): {wrong} drive (id 5), registers 100..105"), (
        p.stderr
    )
    assert said[0].endswith(
        f"Modbus exception 11 (gateway target device failed to respond); no device at {wrong} (id 5): nothing was "
        f"started there, no stop needed; stop sent to {other} (id {other_id})"
    ), p.stderr
    assert "NOT delivered" not in p.stderr and "emergency stop" not in p.stderr
    assert said[-1].startswith("  is that the drive's device id?"), p.stderr
    assert threaded_tcp_sim.regs(other_id)["CW"] == CW_RAMP_STOP  # the drive that is there took the stop
