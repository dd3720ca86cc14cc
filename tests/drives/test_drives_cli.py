"""`orbitrig drives status|run|stop` against the simulator's drives: in a subprocess where the
command is to be signalled or the drives changed while it runs, in this process (typer's runner,
the drives served from another thread) where it runs to its end on its own."""

from __future__ import annotations

import asyncio
import json
import signal
import time

import pytest
from support.cli_helpers import orbitrig, orbitrig_started_async
from support.drives_testkit import CLI_START_S, CW_RAMP_STOP, CW_RUN, exit_with_registers, invoke_cli, run_cli

pytestmark = pytest.mark.timeout(150)  # a hang fails, with a traceback


def test_run_status_stop(threaded_drives):
    sim = threaded_drives
    code, out, err = invoke_cli(
        "drives",
        "run",
        "--modbus",
        sim.url,
        "--spin",
        "1200",
        "--orbit",
        "-600",
        "--max-spin",
        "2000",
        "--max-orbit",
        "1000",
        "--settle",
        "0.1",
        "--timeout",
        "10",
    )
    assert code == 0, err
    assert "spin  (id 1): running, at setpoint" in out
    assert sim.rpm(1) == pytest.approx(1200, abs=5) and sim.rpm(2) == pytest.approx(-600, abs=5)

    code, out, err = invoke_cli("drives", "status", "--modbus", sim.url, "--json")
    assert code == 0, err
    status = json.loads(out)
    assert set(status) == {"modbus", "spin", "orbit"}
    assert status["orbit"]["reference_rpm"] == pytest.approx(-600, abs=0.2)
    assert status["spin"]["parameters"]["speed_scale_rpm"] == 3000
    assert status["spin"]["fault_code"] in (0, 7510)  # the run's client has gone: watchdog

    code, out, err = invoke_cli("drives", "stop", "--modbus", sim.url)
    assert code == 0, err
    assert sim.regs(1)["ACT"] == sim.regs(2)["ACT"] == 0  # returned only at zero


def test_run_refused_by_a_limit_sends_nothing(threaded_tcp_sim):
    tcp_sim = threaded_tcp_sim
    code, out, err = invoke_cli(
        "drives",
        "run",
        "--modbus",
        tcp_sim.url,
        "--spin",
        "1500",
        "--orbit",
        "100",
        "--max-spin",
        "1000",
    )
    assert code == 2
    assert "error (limit)" in err and "spin drive (id 1)" in err and "nothing sent" in err
    for dev in (1, 2):
        assert tcp_sim.regs(dev)["CW"] == 0 and tcp_sim.regs(dev)["REF"] == 0


async def test_run_fails_on_a_trip_and_stops_both(tcp_sim):
    sim = tcp_sim
    task = asyncio.create_task(
        run_cli(
            "drives",
            "run",
            "--modbus",
            sim.url,
            "--spin",
            "1000",
            "--orbit",
            "500",
            "--settle",
            "20",
            "--timeout",
            "30",
        )
    )
    await sim.wait_for(lambda: sim.regs(2)["CW"] == CW_RUN, CLI_START_S, "run started")
    sim.models[2].inject_fault(4210)
    code, out, err = await task
    assert code == 2
    assert "error (fault)" in err and "orbit drive (id 2)" in err and "4210" in err
    assert "both drives stopped" in err  # said once both read zero speed
    assert sim.regs(1)["CW"] == CW_RAMP_STOP and sim.regs(1)["FAULT"] == 0
    assert sim.regs(1)["ACT"] == sim.regs(2)["ACT"] == 0


def test_run_timeout_stops_both(threaded_slow_drives):
    """The timeout's way out waits for both drives at standstill before it exits and says so."""
    sim = threaded_slow_drives
    code, out, err = invoke_cli(
        "drives",
        "run",
        "--modbus",
        sim.url,
        "--spin",
        "2400",
        "--orbit",
        "2400",
        "--settle",
        "1",
        "--timeout",
        "1.0",
    )
    at_exit = [sim.regs(dev) for dev in (1, 2)]
    assert code == 2 and "error (timeout)" in err and "both drives stopped" in err, err
    for dev, regs in zip((1, 2), at_exit):
        assert regs["CW"] == CW_RAMP_STOP and regs["ACT"] == 0 and sim.not_the_watchdog(dev), at_exit


@pytest.mark.parametrize(
    "sig",
    [signal.SIGINT, signal.SIGTERM, signal.SIGHUP, signal.SIGQUIT],
    ids=["SIGINT", "SIGTERM", "SIGHUP", "SIGQUIT"],
)
async def test_signal_during_run_stops_both(slow_drives, sig):
    """A signal before the setpoint is held: both drives ramped to zero and confirmed at
    standstill when the command exits (not later, through the watchdog), then exit 2."""
    sim = slow_drives
    proc = await orbitrig_started_async(
        "drives", "run", "--modbus", sim.url, "--spin", "1500", "--orbit", "-800", "--settle", "30", "--timeout", "60"
    )
    try:
        await sim.wait_for(lambda: sim.regs(1)["SW"] & 0x100 and sim.regs(2)["SW"] & 0x100, CLI_START_S, "at setpoint")
    except BaseException:
        proc.kill()
        await proc.wait()
        raise
    proc.send_signal(sig)
    code, err, at_exit = await exit_with_registers(proc, sim)
    assert code == 2, err
    assert f"interrupted by {sig.name}; both drives stopped" in err
    for dev, regs in zip((1, 2), at_exit):
        assert regs["CW"] == CW_RAMP_STOP and regs["ACT"] == 0 and sim.not_the_watchdog(dev), at_exit


def test_emergency_stop_cli(threaded_tcp_sim):
    sim = threaded_tcp_sim
    code, _, err = invoke_cli(
        "drives",
        "run",
        "--modbus",
        sim.url,
        "--spin",
        "2000",
        "--orbit",
        "1000",
        "--settle",
        "0.05",
    )
    assert code == 0, err
    code, out, err = invoke_cli("drives", "stop", "--modbus", sim.url, "--emergency")
    assert code == 0, err
    assert sim.regs(1)["CW"] == sim.regs(2)["CW"] == 0x047B
    assert sim.regs(1)["ACT"] == sim.regs(2)["ACT"] == 0


def test_stop_still_stops_the_drive_that_answers(threaded_tcp_sim):
    sim = threaded_tcp_sim
    code, _, err = invoke_cli(
        "drives",
        "run",
        "--modbus",
        sim.url,
        "--spin",
        "1500",
        "--orbit",
        "500",
        "--settle",
        "0.05",
    )
    assert code == 0, err
    # device id 3 is not on the network (the TCP gateway answers exception 0x0B)
    code, out, err = invoke_cli("drives", "stop", "--modbus", sim.url, "--orbit-id", "3")
    assert code == 2
    assert "orbit drive (id 3)" in err and "exception 11" in err
    assert "stop word delivered to: spin (id 1)" in err
    assert sim.regs(1)["CW"] == CW_RAMP_STOP
    deadline = time.monotonic() + 3
    while sim.regs(1)["ACT"] != 0:  # the spin drive ramping down, served from the other thread
        assert time.monotonic() < deadline, f"spin standstill not within 3 s: {sim.regs(1)}"
        time.sleep(0.01)


def test_status_on_a_dead_link_exits_2():
    code, out, err = invoke_cli("drives", "status", "--modbus", "tcp://127.0.0.1:9")
    assert code == 2 and "error (link)" in err and "cannot connect" in err


def test_stop_on_a_dead_link_says_each_word_not_delivered_under_the_command():
    """The drives' own warnings read as the command's (they read `orbitrig drives.stop: ...`,
    the logger's name, beside `orbitrig drives stop: error ...`)."""
    p = orbitrig("drives", "stop", "--modbus", "tcp://127.0.0.1:9")
    lines = p.stderr.splitlines()
    assert p.returncode == 2, p.stderr
    said = "orbitrig drives stop: stop command not delivered: spin drive (id 1), register CW (0)"
    assert any(line.startswith(said) for line in lines), p.stderr
    assert not [line for line in lines if line.startswith("orbitrig drives.")], p.stderr
