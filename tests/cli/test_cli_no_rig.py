"""`orbitrig sweep` (and `orbitrig calibrate`) without --sim on a machine without the rig: says
so naming each transport, suggests --sim, leaves no run directory (no record), and the next try
gets the same answer (not "already exists"); `orbitrig drives` with no drive at its address says
what to check, as `orbitrig acquire` does for the A/D board. Commands that find no rig there start
nothing and move no drive: run in the test's process (support.cli_helpers.orbitrig_here)."""

from __future__ import annotations

import errno
import re
import shutil

from orbitrig.config.home import HOME_ENV
from support.cli_helpers import orbitrig, orbitrig_here, reaped, started
from support.ports import free_port
from support.rig_configs import modbus_only_lab, rig_without_answer
from support.paths import ROOT


def test_sweep_without_the_rig_names_each_transport_and_suggests_sim(tmp_path):
    rig, subs = rig_without_answer(tmp_path)
    out = tmp_path / "runs" / "paper"
    for attempt in range(2):
        p = orbitrig_here("sweep", "--config", str(rig), "--matrix", "paper", "--out", str(out))
        assert p.returncode == 2, (attempt, p.stdout, p.stderr)
        assert "the rig does not answer" in p.stderr
        assert f"([transports] and [drives] in {rig}):" in p.stderr  # the drives' line names [drives] ids
        for what in ("A/D board", "drives", "CAN sensor node"):
            assert what in p.stderr
        for url in (subs["adc_url"], subs["modbus_url"], subs["can_channel"]):
            assert url in p.stderr
        assert "--sim" in p.stderr
        assert "already exists" not in p.stderr
        assert "Traceback" not in p.stderr
        assert not out.exists()
        assert not (tmp_path / "runs").exists()


def test_sweep_with_one_transport_missing_names_only_that_one(tmp_path):
    """The drives (the simulator's, read by the check) and the A/D board (a listener) answer; the
    CAN bus does not."""
    import sys

    from support.drives_testkit import SPEEDUP, served_from_a_thread

    rig, subs = rig_without_answer(tmp_path)
    code = (
        "import asyncio, sys\n"
        "async def main():\n"
        "    servers = [await asyncio.start_server(lambda r, w: None, '127.0.0.1', int(p)) for p in sys.argv[1:]]\n"
        "    print('ready', flush=True)\n"
        "    await asyncio.sleep(60)\n"
        "asyncio.run(main())\n"
    )
    ports = [subs["adc_url"].rsplit(":", 1)[1]]
    with (
        served_from_a_thread("tcp", SPEEDUP) as drives,
        reaped(started([sys.executable, "-c", code, *ports], stdin=None, stderr=None)) as listener,
    ):
        rig.write_text(rig.read_text().replace(subs["modbus_url"], drives.url))
        assert listener.stdout.readline().strip() == "ready"
        p = orbitrig("sweep", "--config", str(rig), "--matrix", "demo", "--out", str(tmp_path / "run"), timeout=60)
        assert drives.regs(1)["CW"] == drives.regs(2)["CW"] == 0  # read, nothing written
    assert p.returncode == 2, p.stderr
    assert "CAN sensor node" in p.stderr and subs["can_channel"] in p.stderr
    assert "A/D board" not in p.stderr and "drives (modbus_url" not in p.stderr
    assert not (tmp_path / "run").exists()


def test_calibrate_without_the_rig_names_each_transport_and_writes_no_record(tmp_path):
    rig, subs = rig_without_answer(tmp_path)
    shutil.copytree(ROOT / "config" / "calibration", tmp_path / "calibration")
    before = sorted((tmp_path / "calibration").iterdir())
    p = orbitrig_here("calibrate", "runout", "--config", str(rig))
    assert p.returncode == 2, (p.stdout, p.stderr)
    assert "the rig does not answer" in p.stderr and "no record was written" in p.stderr
    for what, url in (("A/D board", "adc_url"), ("drives", "modbus_url"), ("CAN sensor node", "can_channel")):
        assert what in p.stderr and subs[url] in p.stderr
    assert "--sim" in p.stderr and "Traceback" not in p.stderr and "slow roll:" not in p.stderr
    assert sorted((tmp_path / "calibration").iterdir()) == before


def test_drives_commands_with_no_drive_there_say_what_to_check(tmp_path):
    """(A rig without a CAN node: `drives run` on one with a node opens it first and, with no bus
    there, names it instead, tests/drives/test_drives_run_supply.py.)"""
    url = f"tcp://127.0.0.1:{free_port()}"  # nothing listens there
    lab = modbus_only_lab(tmp_path / "lab")
    for command, args, outcome in (
        ("status", (), ""),
        ("run", ("--spin", "1000", "--orbit", "-500"), "; nothing sent"),
        ("stop", (), "; ramp stop (OFF1, spin (id 1), orbit (id 2) not read) sent; stop word delivered to: no drive"),
    ):
        p = orbitrig_here("drives", command, *args, "--modbus", url, env={HOME_ENV: str(lab)})
        assert p.returncode == 2, (command, p.stderr)
        said = p.stderr.splitlines()
        i = said.index(
            f"orbitrig drives {command}: error (link): cannot connect to {url}: connection refused "
            f"(nothing listens on that port: a wrong port, or the drives' server off){outcome}"
        )
        assert said[i + 1] == (
            "  is the drives' Modbus server (or `orbitrig sim`) serving there? "
            "set [transports] modbus_url in the rig config or pass --modbus"
        ), (command, p.stderr)


def test_sweep_with_a_can_bus_but_no_node_on_it_names_the_heartbeat_id(tmp_path):
    """The A/D board and the drives listen; the CAN bus opens (python-can's virtual bus opens any
    channel, as a real bus opens with its node off) but no node sends: the sweep started, and the
    run found the node lost only later. Now the check waits for the heartbeat (CAN id 0x701)."""
    import socket

    from support.drives_testkit import SPEEDUP, served_from_a_thread

    rig, subs = rig_without_answer(tmp_path)
    channel = f"no-node-{tmp_path.name}"
    text = rig.read_text().replace(f'can_channel = "{subs["can_channel"]}"', f'can_channel = "{channel}"')
    rig.write_text(text.replace('can_interface = "serial"', 'can_interface = "virtual"'))
    listener = socket.create_server(("127.0.0.1", int(subs["adc_url"].rsplit(":", 1)[1])))
    try:
        with served_from_a_thread("tcp", SPEEDUP) as drives:
            rig.write_text(rig.read_text().replace(subs["modbus_url"], drives.url))
            p = orbitrig_here("sweep", "--config", str(rig), "--matrix", "demo", "--out", str(tmp_path / "run"))
            rig.write_text(rig.read_text().replace("spin_id = 1", "spin_id = 5"))
            wrong_id = orbitrig_here("sweep", "--config", str(rig), "--matrix", "demo", "--out", str(tmp_path / "run"))
            words = drives.regs(1)["CW"], drives.regs(2)["CW"]
    finally:
        listener.close()
    assert p.returncode == 2, p.stderr
    assert (
        f"  CAN sensor node (can_interface, can_channel): CAN virtual:{channel}: no heartbeat from node 1 "
        "(CAN id 0x701) within 1.5 s"
    ) in p.stderr.splitlines()[1], p.stderr
    assert "A/D board" not in p.stderr and "drives (modbus_url" not in p.stderr
    # a spin_id no drive has: was a run directory made and the run failed at the drives' opening (exit 1)
    assert wrong_id.returncode == 2, wrong_id.stderr
    assert (
        "  drives (modbus_url, [drives] spin_id, orbit_id): spin drive (id 5), registers 100..105 (SPEED_SCALE .. "
        f"AT_SETPOINT_BAND): request FC03 refused on {drives.url}: Modbus exception 11 (gateway target device "
        "failed to respond)"
    ) in wrong_id.stderr.splitlines(), wrong_id.stderr
    assert words == (0, 0)  # read, nothing written
    assert not (tmp_path / "run").exists()


def test_sweep_says_why_each_connect_failed(tmp_path):
    """The A/D board's and the drives' hosts do not answer the connect (a firewall dropping the
    port), the CAN bus refuses it (said well already): was `cannot connect ()` for the board, `cannot connect to URL:
    TimeoutError()` for the drives and `[Errno 111] Connect call failed (...)` for a refused board."""
    from support.ports import blackholed_port

    rig, subs = rig_without_answer(tmp_path)
    with blackholed_port() as adc, blackholed_port() as modbus:
        text = rig.read_text().replace(subs["adc_url"], f"socket://127.0.0.1:{adc}")
        rig.write_text(text.replace(subs["modbus_url"], f"tcp://127.0.0.1:{modbus}"))
        p = orbitrig_here("sweep", "--config", str(rig), "--matrix", "demo", "--out", str(tmp_path / "run"))
    assert p.returncode == 2, p.stderr
    said = p.stderr.splitlines()
    assert said[1:4] == [
        f"  A/D board (adc_url): socket://127.0.0.1:{adc}: cannot connect (no answer to the connection within "
        "2 s: a wrong or unreachable host, or a firewall dropping the port)",
        f"  drives (modbus_url, [drives] spin_id, orbit_id): cannot connect to tcp://127.0.0.1:{modbus}: no answer to the connection within "
        "2.5 s (a wrong or unreachable host, or a firewall dropping the port)",
        f"  CAN sensor node (can_interface, can_channel): CAN serial:{subs['can_channel']}: cannot open bus "
        f"(Could not open port {subs['can_channel']}: [Errno 111] Connection refused)",
    ], p.stderr
    refused = orbitrig_here("acquire", "--adc", subs["adc_url"])
    assert f"{subs['adc_url']}: cannot connect (connection refused: nothing listens on that port)" in refused.stderr


def test_sweep_with_serial_ports_that_do_not_exist_says_what_to_check(tmp_path):
    """The first morning's rig.toml names /dev/ttyUSB0-like ports the adapters did not get: each
    is named with what to check (the adapters' stable names), exit 2, no run directory."""
    from orbitrig.run.rig_answers import PORT_HINTS

    rig, _ = rig_without_answer(tmp_path)
    adc, drives = tmp_path / "ttyUSB0", tmp_path / "ttyUSB1"  # no such device files
    text = re.sub(r"(?m)^adc_url\s*=.*$", f'adc_url = "{adc}"', rig.read_text())
    rig.write_text(re.sub(r"(?m)^modbus_url\s*=.*$", f'modbus_url = "rtu://{drives}?baud=19200"', text))
    out = tmp_path / "run"
    p = orbitrig_here("sweep", "--config", str(rig), "--matrix", "demo", "--out", str(out))
    assert p.returncode == 2, p.stderr
    said = p.stderr.splitlines()
    adc_at = next(i for i, line in enumerate(said) if line.startswith(f"  A/D board (adc_url): {adc}: cannot open"))
    drives_at = next(i for i, line in enumerate(said) if line.startswith("  drives (modbus_url,"))
    hint = "    " + PORT_HINTS[errno.ENOENT]
    assert said[adc_at + 1] == hint and said[drives_at + 1] == hint, p.stderr
    assert f"cannot open {drives}: " in said[drives_at] and 'OSError("' not in p.stderr
    assert not out.exists()
