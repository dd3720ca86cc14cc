"""`python -m sim`: the simulated rig without the application (as `orbitrig sim`).

Prints the endpoints as one JSON line on stdout once every server listens (the
ready handshake), then serves until SIGINT or SIGTERM. As the child of an
application (`--parent-pid`) it also ends when that process ends or closes its
standard input (sim.parent). docs/protocols/sim-control.md: the control API. Computes with one
BLAS thread unless the environment says how many, as the orbitrig command does (rigthreads).
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import dataclasses
import json
import os
import sys

from rigthreads import one_blas_thread

one_blas_thread()  # as the orbitrig command, before numpy is imported (rigthreads)

from sim.config import CAN_NODE_IDS, CanConfig, SimConfig  # noqa: E402
from sim.scenario_files import load_sim_config, sim_config_from_data  # noqa: E402
from sim.rig import SimRig  # noqa: E402
from sim.serve import end_served, serve_until_signalled  # noqa: E402


def _args(argv: list[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(prog="python -m sim", description=__doc__.split("\n\n")[0])
    ap.add_argument("--config", help="simulator TOML (see config/sim.toml)")
    ap.add_argument("--config-json", help="the simulator configuration as JSON (sim.scenario_files.sim_config_to_data)")
    ap.add_argument("--modbus-port", type=int, default=5020)
    ap.add_argument("--adc-port", type=int, default=5000)
    ap.add_argument(
        "--adc-pty", action=argparse.BooleanOptionalAction, default=True, help="also stream the A/D frames on a pty"
    )
    ap.add_argument("--control-port", type=int, default=0)
    ap.add_argument("--speedup", type=float, default=None)
    ap.add_argument("--modbus-rtu", action="store_true", help="also serve Modbus RTU on a pty")
    ap.add_argument("--can-channel", default=None)
    ap.add_argument("--can-interface", default="virtual")
    ap.add_argument(
        "--can-node-id",
        type=int,
        default=None,
        metavar="N",
        help="the CAN sensor node's node id, 1..127 (its frames 0x180+N, 0x280+N, 0x380+N, heartbeat 0x700+N; "
        "default the scenario's [can] node_id, 1)",
    )
    ap.add_argument(
        "--can-hub",
        type=int,
        default=None,
        metavar="PORT",
        help="the CAN bus between processes: a TCP hub on PORT (0: any free; python-can "
        "interface 'serial', channel socket://127.0.0.1:PORT, sim.can_tcp)",
    )
    ap.add_argument(
        "--nice",
        type=int,
        default=0,
        help="change this process's nice value by N (negative: before the host's other work, "
        "as drives that are machines of their own; ignored where not permitted)",
    )
    ap.add_argument(
        "--parent-pid", type=int, default=None, help="end when this process ends or closes our standard input"
    )
    return ap.parse_args(argv)


def _config(a: argparse.Namespace) -> SimConfig:
    """The scenario of --config-json or --config (default the paper's rig), its CAN node id
    --can-node-id's when given. ValueError naming what is wrong."""
    if a.config_json:
        cfg = sim_config_from_data(json.loads(a.config_json), "--config-json")
    else:
        cfg = load_sim_config(a.config) if a.config else SimConfig()
    if a.can_node_id is None:
        return cfg
    if a.can_node_id not in CAN_NODE_IDS:
        raise ValueError(f"--can-node-id {a.can_node_id}: a CANopen node id is 1..127")
    return dataclasses.replace(cfg, can=CanConfig(node_id=a.can_node_id))  # checked as the scenario's is


async def _serve(a: argparse.Namespace, cfg: SimConfig) -> None:
    from sim.can_tcp import CanTcpHub

    async with contextlib.AsyncExitStack() as stack:
        can = dict(can_channel=a.can_channel, can_interface=a.can_interface)
        if a.can_hub is not None:
            hub = await stack.enter_async_context(CanTcpHub(port=a.can_hub))
            can = dict(can_channel=hub.url, can_interface="serial")
        rig = SimRig(
            cfg,
            speedup=a.speedup,
            modbus_port=a.modbus_port,
            adc_port=a.adc_port,
            adc_pty=a.adc_pty,
            modbus_rtu_pty=a.modbus_rtu,
            control_port=a.control_port,
            **can,
        )
        await serve_until_signalled(rig)


def main(argv: list[str] | None = None) -> int:
    a = _args(argv)
    if a.nice:
        with contextlib.suppress(OSError):  # PermissionError: an unprivileged user may only lower it
            os.nice(a.nice)
    if a.parent_pid is not None:
        from sim.parent import end_with_parent

        end_with_parent(a.parent_pid)
    try:
        cfg = _config(a)
        if a.speedup is not None and not a.speedup > 0:
            raise ValueError("--speedup must be > 0")
    except ValueError as err:  # json.JSONDecodeError included
        print(f"python -m sim: {err}", file=sys.stderr)
        return 2
    try:
        asyncio.run(_serve(a, cfg))
    except (OSError, RuntimeError) as err:  # a port in use (pymodbus: RuntimeError "Could not start listen")
        print(f"python -m sim: {err}", file=sys.stderr)
        return 1
    end_served()  # every server is closed: end now (a parent application waits for it)


if __name__ == "__main__":
    sys.exit(main())
