"""`orbitrig sim`: the software rig in the foreground."""

from __future__ import annotations

import json
import sys

import typer

from orbitrig.cli import sim_options as opt
from orbitrig.cli.failure import fail

#: default TCP port of the simulator's CAN bus (python-can `serial` framing)
CAN_PORT = 5010


def register(app: typer.Typer) -> None:
    @app.command("sim")
    def sim(
        sim_config: opt.SimConfig = None,
        old_config: opt.OldConfig = None,
        modbus_port: opt.ModbusPort = 5020,
        adc_port: opt.AdcPort = 5000,
        speedup: opt.Speedup = None,
        control_port: opt.ControlPort = 0,
        modbus_rtu: opt.ModbusRtu = False,
        can_port: opt.CanPort = CAN_PORT,
        can_channel: opt.CanChannel = None,
        can_interface: opt.CanInterface = "virtual",
        can_node_id: opt.CanNodeId = None,
    ) -> None:
        """Run the simulated rig: drives (Modbus ids 1, 2), A/D board (TCP + pty), CAN sensor node (TCP).

        Prints one JSON line with the endpoints on stdout and what it serves where on
        stderr, then runs until Ctrl-C / SIGTERM. Both drives start stopped; A/D frames
        stream whenever the orbit spindle turns; the CAN node sends all the time.
        """
        import asyncio

        from orbitrig.run.modbus_log import keep_pymodbus_off_the_terminal

        keep_pymodbus_off_the_terminal()  # a client that hangs up before its answer: no hex dump on stderr
        cfg = _sim_config(sim_config, old_config, speedup)
        if can_node_id is not None:
            from dataclasses import replace

            from sim.config import CanConfig

            cfg = replace(cfg, can=CanConfig(node_id=can_node_id))
        ports = dict(modbus_port=modbus_port, adc_port=adc_port, control_port=control_port, modbus_rtu_pty=modbus_rtu)
        try:
            asyncio.run(
                _serve(cfg, speedup, ports, can_port=can_port, can_channel=can_channel, can_interface=can_interface)
            )
        except (OSError, RuntimeError) as err:  # a port in use (pymodbus says RuntimeError "Could not start listen")
            fail(
                f"{err} (ports: Modbus {modbus_port}, A/D {adc_port}, CAN {can_port}, "
                f"control {control_port}; is another simulator running? 0 picks a free port)",
                1,
            )
        from sim.serve import end_served

        end_served()  # every server closed, the CAN node off: no interpreter teardown to wait for


def _sim_config(sim_config, old_config, speedup):
    """The simulator configuration of --sim-config (or its deprecated alias --config, said once: a file
    or a shipped scenario's name; default: the paper's rig); exit 2 if it or --speedup is bad."""
    from orbitrig.cli.scenarios import scenario_file
    from sim.config import SimConfig
    from sim.scenario_files import load_sim_config

    try:
        given, option, note = opt.scenario_option(sim_config, old_config)
    except ValueError as err:
        fail(str(err), 2)
    if note is not None:
        typer.echo(note, err=True)
    path = scenario_file(given, option)
    try:
        cfg = load_sim_config(path) if path is not None else SimConfig()
    except ValueError as err:
        fail(str(err), 2)
    problem = opt.speedup_problem(speedup)
    if problem is not None:
        fail(problem, 2)
    return cfg


async def _serve(cfg, speedup, ports: dict, *, can_port: int, can_channel, can_interface: str) -> None:
    """Serve the simulated rig until a signal ends it; its CAN node on a TCP bus other processes
    reach (at `can_port`), or on `can_channel` when one is given."""
    import contextlib

    from sim.can_tcp import CanTcpHub
    from sim.rig import SimRig
    from sim.serve import serve_until_signalled

    async with contextlib.AsyncExitStack() as stack:
        can = dict(can_channel=can_channel, can_interface=can_interface)
        if can_channel is None:  # the bus other processes can reach
            hub = await stack.enter_async_context(CanTcpHub(port=can_port))
            can = dict(can_channel=hub.url, can_interface="serial")
        rig = SimRig(cfg, speedup=speedup, **ports, **can)
        await serve_until_signalled(rig, out=_Announce(can["can_interface"], speedup or cfg.speedup))


class _Announce:
    """stdout for the endpoints line: passes it on, and tells the operator on stderr
    what is served where."""

    def __init__(self, can_interface: str, speedup: float):
        self.can_interface, self.speedup = can_interface, speedup
        self.told = False

    def write(self, text: str) -> None:
        sys.stdout.write(text)
        if not self.told and text.startswith("{"):
            self.told = True
            sys.stderr.write(describe_endpoints(json.loads(text), self.can_interface, self.speedup))

    def flush(self) -> None:
        sys.stdout.flush()
        sys.stderr.flush()


def describe_endpoints(ep: dict, can_interface: str, speedup: float) -> str:
    """The endpoints object of the simulator in words, with the rig.toml keys that reach them."""
    lines = [
        f"orbitrig sim: the simulated rig runs (simulated time = {speedup:g} x wall time); Ctrl-C ends it.",
        f"  drives     Modbus TCP {ep['modbus']}, device ids 1 (spin) and 2 (orbit)",
    ]
    if ep.get("modbus_rtu"):
        lines.append(f"             Modbus RTU on {ep['modbus_rtu']}")
    pty = f" and the pty {ep['adc_pty']}" if ep.get("adc_pty") else ""
    lines.append(f"  A/D board  {ep['adc']} (TCP serial device server){pty}")
    node = ep.get("can_node_id", 1)
    if ep.get("can"):
        from daq.aux import Frame, can_id_text

        lines.append(
            f"  CAN node   python-can interface '{can_interface}', channel {ep['can']}, node id {node} "
            f"(heartbeat {can_id_text(Frame.HEARTBEAT, node)})"
        )
    if ep.get("control"):
        lines.append(f"  control    {ep['control']} (JSON lines)")
    lines.append(
        "In a lab's rig.toml (`orbitrig init DIR`; the shipped config/ is never edited) [transports]: "
        'adc_url = "%s", modbus_url = "%s"%s.'
        % (
            ep["adc"],
            ep["modbus"],
            f', can_interface = "{can_interface}", can_channel = "{ep["can"]}", can_node_id = {node}'
            if ep.get("can")
            else "",
        )
    )
    return "\n".join(lines) + "\n"
