"""The options of `orbitrig drives status|run|stop` (typer Annotated aliases); speeds in rpm."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer

from orbitrig.cli.config_help import RIG_CONFIG_HELP

Modbus = Annotated[
    Optional[str],
    typer.Option(
        "--modbus",
        help="Modbus URL of the drives: tcp://host:port or rtu:///dev/ttyX?baud=19200 "
        "(default: transports.modbus_url of the rig configuration)",
    ),
]
Config = Annotated[
    Optional[Path],
    typer.Option("--config", help=RIG_CONFIG_HELP),
]
SpinId = Annotated[
    Optional[int], typer.Option(help="Device id of the spin drive (default: drives.spin_id of the rig configuration).")
]
OrbitId = Annotated[
    Optional[int],
    typer.Option(help="Device id of the orbit drive (default: drives.orbit_id of the rig configuration)."),
]
JsonOut = Annotated[bool, typer.Option("--json", help="One JSON object on standard output.")]

# run
Spin = Annotated[float, typer.Option("--spin", help="Spin speed omega, rpm (>= 0).")]
Orbit = Annotated[float, typer.Option("--orbit", help="Orbit speed Omega, rpm; negative = backward whirl.")]
MaxSpin = Annotated[
    Optional[float], typer.Option("--max-spin", help="Refuse a spin speed above this, rpm (<= drives.max_spin_rpm).")
]
MaxOrbit = Annotated[
    Optional[float],
    typer.Option("--max-orbit", help="Refuse an |orbit| speed above this, rpm (<= drives.max_orbit_rpm)."),
]
MinRatio = Annotated[Optional[float], typer.Option("--min-ratio", help="Smallest |Omega|/omega (>= drives.min_ratio).")]
MaxRatio = Annotated[Optional[float], typer.Option("--max-ratio", help="Largest |Omega|/omega (<= drives.max_ratio).")]
Settle = Annotated[float, typer.Option("--settle", help="Seconds both drives must hold AT_SETPOINT.")]
Timeout = Annotated[float, typer.Option("--timeout", help="Seconds to reach the setpoint.")]
Hold = Annotated[
    bool,
    typer.Option(
        "--hold",
        help="Stay at the setpoint, polling (the drives' watchdog heartbeat), until "
        "Ctrl-C, SIGTERM, SIGHUP or SIGQUIT; then ramp both to zero and exit 0 (a second signal "
        "during the ramp: emergency stop, exit 4). A closed standard output does not end the hold.",
    ),
]
StatusEvery = Annotated[float, typer.Option("--status-every", help="With --hold: seconds between status lines.")]

# stop
Emergency = Annotated[bool, typer.Option("--emergency", help="Emergency stop (OFF3, fastest ramp) instead of OFF1.")]
StopTimeout = Annotated[
    Optional[float], typer.Option("--timeout", help="Seconds to reach zero (default: from the ramp times).")
]
