"""`python sim_endpoints_spy.py FILE PYTHON -m orbitrig ARGS...`: the `orbitrig ARGS` command as
`python -m orbitrig` runs it, its simulator (`--sim`) started as ever; the endpoints that simulator
announces are written to FILE (JSON), so that a test reaches its control API (a fault mid-run)."""

from __future__ import annotations

import json
import runpy
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def main() -> None:
    file, command = Path(sys.argv[1]), sys.argv[2:]
    if command[1:3] != ["-m", "orbitrig"]:
        raise SystemExit(f"usage: sim_endpoints_spy.py FILE PYTHON -m orbitrig ARGS... (not {command})")
    sys.path[0] = str(ROOT)  # the source tree, not this folder
    from orbitrig.cli import simulator_process

    ready = simulator_process.SimulatorStart.ready

    async def announced(self: simulator_process.SimulatorStart) -> dict:
        endpoints = await ready(self)
        part = file.with_suffix(".part")
        part.write_text(json.dumps(endpoints))
        part.replace(file)  # whole or not at all
        return endpoints

    simulator_process.SimulatorStart.ready = announced  # type: ignore[method-assign]
    sys.argv = ["orbitrig", *command[3:]]
    runpy.run_module("orbitrig", run_name="__main__", alter_sys=True)


if __name__ == "__main__":
    main()
