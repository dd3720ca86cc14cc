"""Serving a SimRig in the foreground: `python -m sim` and `orbitrig sim`."""

from __future__ import annotations

import asyncio
import json
import signal
import sys

from sim.rig import SimRig


async def serve_until_signalled(rig: SimRig, out=None) -> None:
    """Run ``rig`` in the foreground: print its endpoints as one JSON line on
    ``out`` (stdout), then serve until SIGINT or SIGTERM; exits cleanly."""
    out = out or sys.stdout
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)
    try:
        async with rig:
            ep = rig.endpoints()
            if ep["modbus_rtu"] is None:
                del ep["modbus_rtu"]
            out.write(json.dumps(ep) + "\n")
            out.flush()
            await stop.wait()
    finally:
        for sig in (signal.SIGINT, signal.SIGTERM):
            loop.remove_signal_handler(sig)
