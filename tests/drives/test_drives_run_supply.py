"""`orbitrig drives run --hold` watches the rig's interlocks as a sweep does: the lubricant supply
lost (the pump off) for [interlocks] supply_lost_timeout_s, or the CAN sensor node silent for
can_heartbeat_timeout_s, ends the hold; both drives get the emergency stop (OFF3) and are confirmed
at standstill, the message names the interlock, exit 2. A rig whose CAN node cannot be opened:
nothing sent, exit 2. (Before, the hold watched only the drives: the spindles turned on without oil.)

Real parts: the simulator's rig (its drives behind a real Modbus TCP server, its CAN node on a
python-can `virtual` bus) on an event loop of its own in a thread, the command's own entry
(`_run_command`) in the test's thread; the pump is switched off by the simulator's hands (recess
pressure 0), the node's heartbeat silenced through its fault injection."""

from __future__ import annotations

import asyncio
import os
import signal
import threading
import time
from contextlib import contextmanager

import pytest
import typer
from support.drives_testkit import CW_EMERGENCY, CW_RUN
from support.rig_configs import patient_lab

pytestmark = pytest.mark.timeout(60)

LIMIT_S = 1.0  # [interlocks] supply_lost_timeout_s and can_heartbeat_timeout_s here (wall s)
#: wall s from the cause to the command's end: the limit, the node's 1.5 s of silence before it
#: counts as lost, the emergency stop from 1500 rpm and a loaded machine's margin
ENDS_WITHIN_S = LIMIT_S + 1.5 + 4.0
ARGS = dict(spin=1500.0, orbit=-750.0, max_spin=None, max_orbit=None, min_ratio=None, max_ratio=None)
RUN = dict(settle=0.05, timeout=30.0, hold=True, status_every=60.0, spin_id=None, orbit_id=None)


def _config(folder, channel: str, interface: str = "virtual"):
    """The lab's rig.toml with the CAN node on `channel` and both limits LIMIT_S."""
    path = patient_lab(folder) / "rig.toml"
    text = path.read_text()
    for old, new in (
        ('can_channel = "can0"', f'can_channel = "{channel}"'),
        ('can_interface = "socketcan"', f'can_interface = "{interface}"'),
        ("can_heartbeat_timeout_s = 10.0", f"can_heartbeat_timeout_s = {LIMIT_S}"),
        ("supply_lost_timeout_s = 10.0", f"supply_lost_timeout_s = {LIMIT_S}"),
    ):
        assert old in text, old
        text = text.replace(old, new)
    path.write_text(text)
    return path


@contextmanager
def _sim_rig(channel: str):
    """sim.rig.SimRig on its own event loop in a thread: (the rig, a call into its loop)."""
    from sim.rig import SimRig

    ready, box = threading.Event(), {}

    async def serve():
        box["stop"] = asyncio.Event()
        async with SimRig(speedup=20, adc_pty=False, can_channel=channel) as rig:
            box["rig"], box["loop"] = rig, asyncio.get_running_loop()
            ready.set()
            await box["stop"].wait()

    t = threading.Thread(target=asyncio.run, args=(serve(),), daemon=True)
    t.start()
    assert ready.wait(20)
    try:
        yield box["rig"], lambda fn: box["loop"].call_soon_threadsafe(fn)
    finally:
        box["loop"].call_soon_threadsafe(box["stop"].set)
        t.join(20)


def _cause_once_held(rig, call, cause, t0: list[float]) -> threading.Thread:
    """`cause` called in the simulator's loop once both spindles hold the setpoint; a SIGTERM
    ENDS_WITHIN_S later ends a hold that nothing else ended (so the test fails, not hangs)."""

    def act():
        deadline = time.monotonic() + 20
        while not all(abs(w) > 0.9 * abs(rpm) * 2 * 3.14159 / 60 for w, rpm in zip(rig.speeds, (1500, -750))):
            if time.monotonic() > deadline:
                return
            time.sleep(0.02)
        time.sleep(0.3)  # the command holding
        t0.append(time.monotonic())
        call(cause)
        time.sleep(ENDS_WITHIN_S + 5.0)
        if rig.drives[1].read(0, 1)[0] == CW_RUN:
            os.kill(os.getpid(), signal.SIGTERM)

    thread = threading.Thread(target=act, daemon=True)
    thread.start()
    return thread


@pytest.mark.parametrize(
    "cause, words",
    [
        (lambda rig: rig.set_manual(recess_pressure=0.0), f"lubricant supply pump is off for more than {LIMIT_S:g} s"),
        (lambda rig: rig.inject("can_heartbeat_loss", on=True), f"CAN sensor node lost for more than {LIMIT_S:g} s"),
    ],
    ids=["pump-off", "can-node-silent"],
)
def test_the_hold_ends_with_the_emergency_stop_on_a_lost_supply(tmp_path, capsys, cause, words):
    import orbitrig.cli.drives as cli

    channel = f"drives-run-{os.getpid()}-{time.monotonic_ns()}"
    config = _config(tmp_path / "lab", channel)
    t0: list[float] = []
    with _sim_rig(channel) as (rig, call):
        watcher = _cause_once_held(rig, call, lambda: cause(rig), t0)
        with pytest.raises(typer.Exit) as ended:
            cli._run_command(modbus=rig.modbus_url, config=config, **ARGS, **RUN)
        took = time.monotonic() - t0[0]
        words_now = [rig.drives[dev].read(0, 1)[0] for dev in (1, 2)]
        speeds = rig.speeds
    watcher.join(0)
    said = capsys.readouterr()
    err = said.err
    assert ended.value.exit_code == 2, err
    assert "orbitrig drives run: error (interlock): after " in err and words in err, err
    assert "emergency stop of both drives (OFF3)" in err and "the hold was ended by an interlock" in said.out, said
    assert LIMIT_S <= took < ENDS_WITHIN_S, took
    assert words_now == [CW_EMERGENCY, CW_EMERGENCY], [hex(w) for w in words_now]
    assert all(abs(w) < 1e-3 for w in speeds), speeds


def test_a_can_node_that_cannot_be_opened_sends_nothing(tmp_path, capsys, tcp_sim):
    import orbitrig.cli.drives as cli

    config = _config(tmp_path / "lab", "no-such-can", interface="socketcan")
    with pytest.raises(typer.Exit) as ended:
        cli._run_command(modbus=tcp_sim.url, config=config, **ARGS, **RUN)
    err = capsys.readouterr().err
    assert ended.value.exit_code == 2, err
    assert "orbitrig drives run: error (can): CAN socketcan:no-such-can: cannot open bus" in err, err
    assert "the lubricant supply and the CAN node cannot be watched; nothing sent" in err, err
    # which file named the node, and the simulator's node for a machine without the rig
    assert f"; [transports] in {config}: the lubricant supply" in err, err
    assert 'can_interface = "serial", can_channel = "socket://127.0.0.1:5010"' in err, err
    assert all(tcp_sim.regs(dev)["CW"] != CW_RUN and tcp_sim.rpm(dev) == 0 for dev in (1, 2))


@pytest.mark.parametrize("node_id", [None, 2], ids=["no-node-on-the-bus", "another-node-id"])
def test_a_can_node_not_heard_sends_nothing(tmp_path, capsys, tcp_sim, node_id):
    """A bus that opens with no node on it (python-can's virtual bus opens any channel; on the rig:
    the node off, another bitrate), or [transports] can_node_id 2 where the node is 1: the drives
    started before and the node was found lost only can_heartbeat_timeout_s later, the spindles
    turning meanwhile with the supply unknown."""
    import orbitrig.cli.drives as cli

    channel = f"drives-run-unheard-{os.getpid()}-{time.monotonic_ns()}"
    config = _config(tmp_path / "lab", channel)
    if node_id is not None:
        config.write_text(config.read_text().replace("can_node_id = 1", f"can_node_id = {node_id}"))
    t0 = time.monotonic()
    with _sim_rig(channel if node_id is not None else channel + "-elsewhere"):
        with pytest.raises(typer.Exit) as ended:
            cli._run_command(modbus=tcp_sim.url, config=config, **ARGS, **RUN)
    took = time.monotonic() - t0
    err = capsys.readouterr().err
    want = node_id or 1
    # the node on the bus answers as node 1: said, when it is not the one rig.toml reads
    heard = (
        "" if node_id is None else "; heartbeat 0x701 heard (node 1), not node 2's 0x702 ([transports] can_node_id 2)"
    )
    assert ended.value.exit_code == 2, err
    assert (
        f"orbitrig drives run: error (can): CAN virtual:{channel}: no heartbeat from node {want} "
        f"(CAN id 0x{0x700 + want:03X}) within 1.5 s{heard} (the node off or on another bus, or [transports] "
        f"can_node_id {want} or can_bitrate 500000 not the node's); [transports] in {config}: the lubricant "
        "supply and the CAN node cannot be watched; nothing sent"
    ) in err, err
    assert all(tcp_sim.regs(dev)["CW"] == 0 and tcp_sim.rpm(dev) == 0 for dev in (1, 2))
    assert took < 15, took
