"""`python -m sim`: the simulated rig without the application (same as `orbitrig sim`)."""

from __future__ import annotations

import argparse
import asyncio
import sys

from sim.config import SimConfig, load_sim_config
from sim.rig import SimRig, serve_until_signalled


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m sim", description=__doc__)
    ap.add_argument("--config", help="simulator TOML (see config/sim.toml)")
    ap.add_argument("--modbus-port", type=int, default=5020)
    ap.add_argument("--adc-port", type=int, default=5000)
    ap.add_argument("--control-port", type=int, default=0)
    ap.add_argument("--speedup", type=float, default=None)
    ap.add_argument("--modbus-rtu", action="store_true", help="also serve Modbus RTU on a pty")
    ap.add_argument("--can-channel", default=None)
    ap.add_argument("--can-interface", default="virtual")
    a = ap.parse_args(argv)
    try:
        cfg = load_sim_config(a.config) if a.config else SimConfig()
        if a.speedup is not None and not a.speedup > 0:
            raise ValueError("--speedup must be > 0")
    except ValueError as err:
        print(f"python -m sim: {err}", file=sys.stderr)
        return 2
    rig = SimRig(cfg, speedup=a.speedup, modbus_port=a.modbus_port, adc_port=a.adc_port,
                 modbus_rtu_pty=a.modbus_rtu, can_channel=a.can_channel,
                 can_interface=a.can_interface, control_port=a.control_port)
    try:
        asyncio.run(serve_until_signalled(rig))
    except OSError as err:
        print(f"python -m sim: {err}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
