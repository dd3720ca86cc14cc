"""`orbitrig drives run`: the rig's interlocks watched while the command has the drives open.

With a CAN sensor node in the rig configuration ([interlocks] check_can_heartbeat or
check_supply_pressure on), `run` opens the node before the drives (one that cannot be opened,
or whose heartbeat is not read within 1.5 s: nothing sent) and samples the run's own interlocks (orbitrig.run.supervision.InterlockSupervisor,
as a sweep and a calibration step do) for as long as it holds the drives: the lubricant supply
lost (pump off, supply below its minimum) for [interlocks] supply_lost_timeout_s, or the node
lost or mute for can_heartbeat_timeout_s, ends the command; both drives get the emergency stop
(OFF3), as a sweep's on a supply loss, and the message names the interlock
(drives_hold.Interrupt.on_interlock). A drive's trip or lost link is the poll's to say.
"""

from __future__ import annotations

import asyncio
import contextlib

from orbitrig.config import Interlocks, RigConfig
from orbitrig.run.interlocks import Trip, TripKind
from orbitrig.run.rig_io import can_node
from orbitrig.run.supervision import InterlockSupervisor

#: what the drives' own poll finds and says (drives_hold: the way out names the drive)
POLL_KINDS = frozenset({TripKind.DRIVE_TRIP, TripKind.DRIVE_LINK, TripKind.DRIVE_POLL})


def watches_can_node(cfg: Interlocks) -> bool:
    """The rig configuration has a CAN node its interlocks count on."""
    return cfg.check_can_heartbeat or cfg.check_supply_pressure


class DrivesWatch:
    """The interlocks of `cfg` on the open CAN node `aux` and the drives' latest poll, sampled in a
    task of their own from `start` until `close`."""

    def __init__(self, aux, cfg: Interlocks) -> None:
        self._aux, self._cfg = aux, cfg
        self._task: asyncio.Task[None] | None = None

    def start(self, rig, interrupt) -> None:
        """Watch while `rig` (RigDrives, open) turns; a fail trip goes to `interrupt.on_interlock`
        with the command's task."""
        command = asyncio.current_task()
        assert command is not None

        def failed(trip: Trip) -> None:
            if trip.kind not in POLL_KINDS:
                interrupt.on_interlock(trip, command)

        supervisor = InterlockSupervisor(lambda: (self._aux.latest(), rig.state), self._cfg, failed)
        self._task = asyncio.create_task(supervisor.watch(), name="drives-run-interlocks")

    async def close(self) -> None:
        if self._task is not None:
            self._task.cancel()
            await asyncio.gather(self._task, return_exceptions=True)


async def opened_watch(stack: contextlib.AsyncExitStack, rig: RigConfig) -> DrivesWatch | None:
    """The watch of `rig`'s CAN node, entered on `stack` (closed with it), or None if the rig
    configuration has none; raises DaqError naming the bus if the node cannot be opened, or its
    CAN id if its heartbeat is not read within 1.5 s (daq.aux.LOST_AFTER: the node lost)."""
    if not watches_can_node(rig.interlocks):
        return None
    aux = await stack.enter_async_context(can_node(rig))
    await aux.heard()
    watch = DrivesWatch(aux, rig.interlocks)
    stack.push_async_callback(watch.close)
    return watch


def unopened_node(err: Exception, rig: RigConfig) -> str:
    """What `run` says of a CAN node `rig` names that cannot be opened: the file whose
    [transports] named it and, for a machine without the rig, the simulator's node."""
    from orbitrig.cli.sim import CAN_PORT

    return (
        f"{err}; [transports] in {rig.file}: the lubricant supply and the CAN node cannot be watched; "
        f"nothing sent. On the simulator (`orbitrig sim`), give a rig.toml whose [transports] name its node: "
        f'can_interface = "serial", can_channel = "socket://127.0.0.1:{CAN_PORT}" (its first lines say which)'
    )
