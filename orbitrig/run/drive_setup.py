"""From the rig configuration's [drives] section to the drives: the one factory.

`orbitrig sweep`/`serve` (through `RigIO`) and `orbitrig drives` build their
limits, their `RigDrives` and their bare (spin, orbit) pair here.
"""

from __future__ import annotations

import math

from drives.drive import Drive
from drives.limits import DriveLimits
from drives.link import ModbusLink
from drives.pair import drive_names, drive_pair
from drives.rig import RigDrives
from orbitrig.config import RPM, Drives

#: no speed or ratio limit (status and stop of `orbitrig drives` command no speed)
UNLIMITED = DriveLimits(math.inf, math.inf)


def drive_limits(d: Drives) -> DriveLimits:
    """The configured speed (rad/s) and orbit/spin ratio limits of [drives]."""
    return DriveLimits(
        max_spin=d.max_spin_rpm * RPM, max_orbit=d.max_orbit_rpm * RPM, min_ratio=d.min_ratio, max_ratio=d.max_ratio
    )


def rig_drives(url: str, d: Drives, limits: DriveLimits | None = None, *, watchdog: bool = False) -> RigDrives:
    """RigDrives at `url` with the configured ids, timeout, poll interval and link-loss polls;
    `limits` default to the configured ones. ``watchdog``: the drives are given the configured
    ``comm_loss_timeout_s`` on entry (their parameters are volatile: a power cycle restores
    the drive's default), as a run needs; a status read leaves them as they are."""
    return RigDrives(
        url,
        drive_limits(d) if limits is None else limits,
        poll_interval=d.poll_interval_s,
        spin_id=d.spin_id,
        orbit_id=d.orbit_id,
        timeout=d.timeout_s,
        link_loss_polls=d.link_loss_polls,
        comm_loss_timeout=d.comm_loss_timeout_s if watchdog else None,
    )


def modbus_link(url: str, d: Drives) -> ModbusLink:
    """A bare Modbus link to both drives (names by the configured ids)."""
    return ModbusLink(url, timeout=d.timeout_s, names=drive_names(d.spin_id, d.orbit_id))


def bare_drives(link: ModbusLink, d: Drives) -> tuple[Drive, Drive]:
    """(spin, orbit) on `link` at the configured ids, without RigDrives' supervision."""
    return drive_pair(link, d.spin_id, d.orbit_id)
