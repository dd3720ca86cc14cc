"""Interlocks: conditions that suspend or fail a run (pure, no I/O).

Like bluesky's suspenders: `check()` looks at the latest CAN sensor state and
drive state and returns the trips in force. A trip with action ``suspend``
holds the run until the condition clears (then the current block is settled
and acquired again); ``fail`` ends the run (both drives stopping).

| kind            | source                                 | action  |
|-----------------|----------------------------------------|---------|
| drive_trip      | a drive reports a fault (TRIPPED/FAULT)| fail    |
| drive_link      | the Modbus link to the drives is down  | fail    |
| can_heartbeat   | no CAN heartbeat for 1.5 s (node lost) | suspend |
| supply_pressure | p_supply outside the configured band   | suspend |
| supply_pump     | the node reports the supply pump off   | suspend |

A lost orbit trigger shows as an acquisition that gets no revolutions; the
executor retries it and then fails the run (it is not polled here).
"""

from __future__ import annotations

from dataclasses import dataclass

from orbitrig.config import MPA, Interlocks

SUSPEND, FAIL = "suspend", "fail"


@dataclass(frozen=True)
class Trip:
    kind: str
    action: str  # suspend | fail
    message: str


def drive_status(state, which: str):
    """The per-drive status object ('spin' | 'orbit') of a RigDriveState, or None."""
    return getattr(state, which, None) if state is not None else None


def check(aux, drives, cfg: Interlocks, *, pressure_armed: bool) -> list[Trip]:
    """Trips in force given the latest AuxState `aux` and RigDriveState `drives` (either may be None)."""
    trips: list[Trip] = []
    if drives is not None:
        if getattr(drives, "link_ok", True) is False:
            trips.append(Trip("drive_link", FAIL, "Modbus link to the drives lost"))
        for which in ("spin", "orbit"):
            st = drive_status(drives, which)
            if st is None:
                continue
            code = int(getattr(st, "fault_code", 0) or 0)
            if code or getattr(st, "tripped", False):
                fault = getattr(st, "fault", "") or ""
                trips.append(Trip("drive_trip", FAIL, f"{which} drive tripped: fault {code} {fault}".rstrip()))
    if aux is not None:
        if cfg.check_can_heartbeat and getattr(aux, "node_lost", False):
            trips.append(Trip("can_heartbeat", SUSPEND, "CAN sensor node lost (no heartbeat for 1.5 s)"))
        elif pressure_armed and cfg.check_supply_pressure:
            if getattr(aux, "pump_off", False):
                trips.append(Trip("supply_pump", SUSPEND, "lubricant supply pump is off"))
            p = getattr(aux, "p_supply", None)
            stale = getattr(aux, "stale", None)
            if p is not None and not (callable(stale) and stale("p_supply")):
                lo, hi = cfg.supply_pressure_min_mpa, cfg.supply_pressure_max_mpa
                if not lo * MPA <= p <= hi * MPA:
                    trips.append(Trip("supply_pressure", SUSPEND,
                                      f"supply pressure {p / MPA:.3f} MPa outside the band {lo:g}..{hi:g} MPa"))  # fmt: skip
    return trips
