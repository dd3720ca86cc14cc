"""The rows of the run file's CAN and drive logs (columns: orbitrig.store.writer CAN_FIELDS, DRIVE_FIELDS),
and the run's monitor that samples them."""

from __future__ import annotations

import asyncio
import logging
import math
import time
from collections.abc import Callable
from typing import TYPE_CHECKING

from daq.aux import AuxState
from drives.drive import DriveStatus
from drives.state import RigDriveState

if TYPE_CHECKING:
    from orbitrig.run.rig_io import RigIO
    from orbitrig.store.writer import RunStore

log = logging.getLogger(__name__)


def can_row(t: float, aux: AuxState) -> tuple[float, ...]:
    """t (s since the run started), temperatures, flow, pressures (SI), flags as 0/1."""
    pr = [float(v) for v in aux.p_recess][:4]
    pr += [math.nan] * (4 - len(pr))
    return (
        t,
        aux.t_recess,
        aux.t_groove,
        aux.t_supply,
        aux.flow,
        aux.p_supply,
        *pr,
        aux.beta,
        float(aux.sensor_fault),
        float(aux.pump_off),
        float(aux.node_lost),
    )


def _drive_values(d: DriveStatus | None) -> list[float]:
    if d is None:
        return [math.nan] * 5
    return [float(d.reference), float(d.actual), float(d.status_word), float(d.fault_code), float(d.torque)]


def drive_row(t: float, st: RigDriveState) -> tuple[float, ...]:
    """t, reference and actual speeds (rad/s), status words, fault codes, torques of spin and orbit."""
    s, o = _drive_values(st.spin), _drive_values(st.orbit)
    return (t, s[0], s[1], o[0], o[1], s[2], o[2], s[3], o[3], s[4], o[4])


async def monitor(store: RunStore, io: Callable[[], RigIO | None], t0: float) -> None:
    """CAN and drive logs of the open rig `io()` every 0.5 s (wall), kept in `store` until its next
    write; t: s since `t0` (monotonic). A failed sample is logged; the next one is still taken."""
    while True:
        t = time.monotonic() - t0
        try:
            rig = io()
            if rig is not None and rig.aux is not None and rig.drives is not None:
                store.logs.add("can", can_row(t, rig.aux.latest()))
                store.logs.add("drives", drive_row(t, rig.drives.state))
        except Exception:  # logging must not break the run
            log.debug("monitor sample failed", exc_info=True)
        await asyncio.sleep(0.5)
