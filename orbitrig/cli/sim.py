"""`orbitrig sim`: the software rig in the foreground."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer


def register(app: typer.Typer) -> None:
    @app.command("sim")
    def sim(
        config: Optional[Path] = typer.Option(None, "--config", help="Simulator TOML (see config/sim.toml)."),
        modbus_port: int = typer.Option(5020, "--modbus-port", min=0, max=65535, help="Modbus TCP port of both drives (0 = any free)."),
        adc_port: int = typer.Option(5000, "--adc-port", min=0, max=65535, help="A/D TCP serial device server port (0 = any free)."),
        speedup: Optional[float] = typer.Option(None, "--speedup", help="Simulated time / wall time (default from config, 1)."),
        control_port: int = typer.Option(0, "--control-port", min=0, max=65535, help="JSON-lines control API port (0 = any free)."),
        modbus_rtu: bool = typer.Option(False, "--modbus-rtu/--no-modbus-rtu", help="Also serve Modbus RTU on a pty."),
        can_channel: Optional[str] = typer.Option(None, "--can-channel", help="python-can channel of the CAN node."),
        can_interface: str = typer.Option("virtual", "--can-interface", help="python-can interface of the CAN node."),
    ) -> None:
        """Run the simulated rig: drives (Modbus ids 1, 2), A/D board (TCP + pty), CAN node.

        Prints one JSON line with the endpoints, then runs until Ctrl-C / SIGTERM.
        Both drives start stopped; A/D frames stream whenever the orbit spindle turns.
        """
        import asyncio

        from sim.config import SimConfig, load_sim_config
        from sim.rig import SimRig, serve_until_signalled

        try:
            cfg = load_sim_config(config) if config is not None else SimConfig()
        except ValueError as err:
            typer.echo(f"orbitrig sim: {err}", err=True)
            raise typer.Exit(2) from err
        if speedup is not None and not speedup > 0:
            typer.echo("orbitrig sim: --speedup must be > 0", err=True)
            raise typer.Exit(2)

        async def run() -> None:
            await serve_until_signalled(SimRig(
                cfg, speedup=speedup, modbus_port=modbus_port, adc_port=adc_port,
                modbus_rtu_pty=modbus_rtu, can_channel=can_channel, can_interface=can_interface,
                control_port=control_port))

        try:
            asyncio.run(run())
        except (OSError, RuntimeError) as err:  # a port in use (pymodbus says RuntimeError "Could not start listen")
            typer.echo(f"orbitrig sim: {err} (ports: Modbus {modbus_port}, A/D {adc_port}, control {control_port}; "
                       "is another simulator running? 0 picks a free port)", err=True)  # fmt: skip
            raise typer.Exit(1) from None
