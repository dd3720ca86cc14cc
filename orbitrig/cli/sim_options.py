"""The options of `orbitrig sim` (typer Annotated aliases): ports, time scale, CAN bus."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer


#: simulated time / wall time of a simulator started by sweep, calibrate or serve --sim
DEFAULT_SPEEDUP = 40.0
#: the largest time scale any command takes: the simulator's own limit (sim.config.MAX_SPEEDUP, which
#: the simulator checks itself; a test holds them equal), here so that the command line can check it
#: without loading the simulator
MAX_SPEEDUP = 1e4


def speedup_problem(speedup: float | None) -> str | None:
    """What is wrong with a --speedup that typer does not bound itself (sim's, serve's): not a
    finite factor > 0 of at most MAX_SPEEDUP (NaN and infinities included); None if given right or not given."""
    if speedup is None or 0 < speedup <= MAX_SPEEDUP:
        return None
    return f"--speedup {speedup:g}: a finite factor > 0 and at most {MAX_SPEEDUP:g}"


#: where a --sim-config help names the shipped scenarios: filled in only when a help is drawn
#: (`fill_scenarios`), so that no other command reads their folder (sim.scenario_files) at its start
SCENARIOS = "{shipped scenarios}"
#: every command's --sim-config help: the shipped scenarios' names as their folder gives them
SCENARIO_HELP = (
    "simulator scenario TOML (default the paper's rig, config/sim.toml); a shipped one by NAME: "
    f"{SCENARIOS} (config/sim/)"
)


def fill_scenarios(command: object) -> None:
    """Name the shipped scenarios (orbitrig.cli.scenarios.shipped_scenarios) in the help of each of
    ``command``'s options whose help has SCENARIOS: done by every command (help_text.Command) just
    before its help is drawn."""
    import typer.core

    if not isinstance(command, typer.core.TyperCommand):
        return
    for param in command.params:
        if isinstance(param, typer.core.TyperOption) and param.help and SCENARIOS in param.help:
            from orbitrig.cli.scenarios import shipped_scenarios

            param.help = param.help.replace(SCENARIOS, ", ".join(shipped_scenarios()))


SimConfig = Annotated[Optional[Path], typer.Option("--sim-config", metavar="NAME|FILE", help=SCENARIO_HELP)]
#: the scenario's option before --sim-config (every other command's --config is rig.toml): still taken, said deprecated
OldConfig = Annotated[Optional[Path], typer.Option("--config", metavar="NAME|FILE", hidden=True)]
#: what `orbitrig sim --config` says, once
OLD_CONFIG_NOTE = (
    "orbitrig sim: note: --config is deprecated here: give the simulator scenario as --sim-config, as sweep and "
    "calibrate do (--config names a rig.toml everywhere else)"
)


def scenario_option(sim_config: Path | None, old_config: Path | None) -> tuple[Path | None, str, str | None]:
    """(the scenario given, the option it was given with, a note to say once or None) of `orbitrig sim`'s
    --sim-config and its deprecated alias --config; ValueError when both are given."""
    if old_config is None:
        return sim_config, "--sim-config", None
    if sim_config is not None:
        raise ValueError("--sim-config and --config both given: give the scenario once, as --sim-config")
    return old_config, "--config", OLD_CONFIG_NOTE


ModbusPort = Annotated[
    int, typer.Option("--modbus-port", min=0, max=65535, help="Modbus TCP port of both drives (0 = any free).")
]
AdcPort = Annotated[
    int, typer.Option("--adc-port", min=0, max=65535, help="A/D TCP serial device server port (0 = any free).")
]
Speedup = Annotated[
    Optional[float], typer.Option("--speedup", help="Simulated time / wall time (default from config, 1).")
]
ControlPort = Annotated[
    int, typer.Option("--control-port", min=0, max=65535, help="JSON-lines control API port (0 = any free).")
]
ModbusRtu = Annotated[bool, typer.Option("--modbus-rtu/--no-modbus-rtu", help="Also serve Modbus RTU on a pty.")]
CanPort = Annotated[
    int,
    typer.Option(
        "--can-port",
        min=0,
        max=65535,
        help="TCP port of the CAN bus: python-can interface 'serial', channel socket://127.0.0.1:PORT (0 = any free).",
    ),
]
CanChannel = Annotated[
    Optional[str],
    typer.Option(
        "--can-channel",
        help="Put the CAN node on this python-can channel instead (e.g. vcan0 with --can-interface socketcan).",
    ),
]
CanInterface = Annotated[str, typer.Option("--can-interface", help="python-can interface of --can-channel.")]
CanNodeId = Annotated[
    Optional[int],
    typer.Option(
        "--can-node-id",
        min=1,
        max=127,
        help="The CAN sensor node's node id (its frames 0x180+N, 0x280+N, 0x380+N, heartbeat 0x700+N; default "
        "the scenario's [can] node_id, 1): as [transports] can_node_id in the rig.toml that reads it.",
    ),
]
