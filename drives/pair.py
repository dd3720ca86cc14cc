"""The rig's two drives on one Modbus link: the spin drive turns one way, the orbit drive both.

`drive_pair` is the one place that knows which drive is which; `RigDrives`
and the best-effort stop of `orbitrig drives stop` both build their drives here.
"""

from __future__ import annotations

from drives.drive import Drive
from drives.link import ModbusLink


def drive_names(spin_id: int, orbit_id: int) -> dict[int, str]:
    """Modbus device id -> drive name, for the link's messages."""
    if spin_id == orbit_id:
        raise ValueError(f"spin_id and orbit_id are both {spin_id}")
    return {spin_id: "spin", orbit_id: "orbit"}


def drive_pair(link: ModbusLink, spin_id: int, orbit_id: int, *, state_timeout: float = 2.0) -> tuple[Drive, Drive]:
    """(spin, orbit) drives at the given device ids of `link`."""
    drive_names(spin_id, orbit_id)
    spin = Drive(link, spin_id, "spin", bidirectional=False, state_timeout=state_timeout)
    orbit = Drive(link, orbit_id, "orbit", bidirectional=True, state_timeout=state_timeout)
    return spin, orbit
