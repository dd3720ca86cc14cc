"""Fault injection into a running SimRig: the faults it knows and what each one does."""

from __future__ import annotations

from enum import StrEnum
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from sim.rig import SimRig


class SimFault(StrEnum):
    """The faults `SimRig.inject` knows (the `fault` field of the control API's `inject`)."""

    CORRUPT_BYTES = "corrupt_bytes"
    DROP_FRAMES = "drop_frames"
    MISSING_TRIGGER = "missing_trigger"
    STALL_CLOCK = "stall_clock"
    CLOSE_ADC_LINK = "close_adc_link"
    ADC_BOARD_GONE = "adc_board_gone"
    DRIVE_TRIP = "drive_trip"
    DRIVE_POWER_CYCLE = "drive_power_cycle"
    MODBUS_TIMEOUT = "modbus_timeout"
    CAN_HEARTBEAT_LOSS = "can_heartbeat_loss"
    CAN_NODE_SILENT = "can_node_silent"
    ORBIT_WIRED_REVERSED = "orbit_wired_reversed"
    CLEAR = "clear"


def inject(rig: SimRig, fault: str, **kw: Any) -> None:
    """Inject `fault` into `rig`; counts and switches as keywords:
    corrupt_bytes(count=1), drop_frames(count=1), missing_trigger(count=1),
    stall_clock(on=True), close_adc_link(reopen_after=1.0 s wall),
    adc_board_gone(back_after=None: for good, else wall s; nothing listens meanwhile),
    drive_trip(drive=1|2, code=2310), drive_power_cycle(drive=1|2), modbus_timeout(on=True),
    can_heartbeat_loss(on=True), can_node_silent(on=True: no frame at all, heartbeat included),
    orbit_wired_reversed(on=True: the orbit turns against its drive's speed, which reads as commanded),
    clear (every fault off, drive causes gone, a board gone back).
    An unknown fault or drive raises ValueError."""
    try:
        which = SimFault(fault)
    except ValueError:
        raise ValueError(f"unknown fault {fault!r}; known: {', '.join(SimFault)}") from None
    b = rig.board
    if which is SimFault.CORRUPT_BYTES:
        b.corrupt += int(kw.get("count", 1))
    elif which is SimFault.DROP_FRAMES:
        b.drop += int(kw.get("count", 1))
    elif which is SimFault.MISSING_TRIGGER:
        b.missed_triggers += int(kw.get("count", 1))
    elif which is SimFault.STALL_CLOCK:
        b.stalled = bool(kw.get("on", True))
    elif which is SimFault.CLOSE_ADC_LINK:
        rig.adc_server.close_link(reopen_after=float(kw.get("reopen_after", 1.0)))
    elif which is SimFault.ADC_BOARD_GONE:
        back = kw.get("back_after")
        rig.adc_server.gone(back_after=None if back is None else float(back))
    elif which in (SimFault.DRIVE_TRIP, SimFault.DRIVE_POWER_CYCLE):
        drive = int(kw.get("drive", 2))
        if drive not in rig.drives:
            raise ValueError(f"{which.value}: no drive {drive} (1 = spin, 2 = orbit)")
        if which is SimFault.DRIVE_TRIP:
            rig.drives[drive].inject_fault(int(kw.get("code", 2310)))
        else:
            rig.drives[drive].power_cycle()
    elif which is SimFault.MODBUS_TIMEOUT:
        for ep in rig.modbus_servers:
            ep.set_unresponsive(bool(kw.get("on", True)))
    elif which is SimFault.CAN_HEARTBEAT_LOSS:
        if rig.can_node is not None:
            rig.can_node.heartbeat_lost = bool(kw.get("on", True))
    elif which is SimFault.CAN_NODE_SILENT:
        if rig.can_node is not None:
            rig.can_node.silent = bool(kw.get("on", True))
    elif which is SimFault.ORBIT_WIRED_REVERSED:
        rig.orbit_reversed = bool(kw.get("on", True))
    else:  # SimFault.CLEAR
        _clear(rig)


def _clear(rig: SimRig) -> None:
    """Every injected fault off and the drives' fault causes gone (a RESET still clears a trip)."""
    b = rig.board
    b.corrupt = b.drop = b.missed_triggers = 0
    b.stalled = rig.orbit_reversed = False
    rig.adc_server.back()
    for ep in rig.modbus_servers:
        ep.set_unresponsive(False)
    for d in rig.drives.values():
        d.clear_fault_cause()
    if rig.can_node is not None:
        rig.can_node.heartbeat_lost = rig.can_node.silent = False
