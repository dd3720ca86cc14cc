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
engine retries it and then fails the run (it is not polled here).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

from daq.aux import AuxState
from drives.state import RigDriveState
from orbitrig.config import MPA, Interlocks


class TripAction(StrEnum):
    """What a trip does to the run: hold it until the condition clears, or end it."""

    __repr__ = str.__repr__  # messages show 'suspend', as the plain string did

    SUSPEND = "suspend"
    FAIL = "fail"


SUSPEND, FAIL = TripAction


@dataclass(frozen=True)
class Trip:
    kind: str
    action: TripAction
    message: str


def check(aux: AuxState | None, drives: RigDriveState | None, cfg: Interlocks, *, pressure_armed: bool) -> list[Trip]:
    """Trips in force given the latest CAN sensor state `aux` and drive state `drives` (either may be None).
    The supply pressure is watched only once `pressure_armed` (the point's pressures were verified)."""
    trips = _drive_trips(drives) if drives is not None else []
    if aux is not None:
        trips += _supply_trips(aux, cfg, pressure_armed)
    return trips


def _drive_trips(drives: RigDriveState) -> list[Trip]:
    trips = []
    if not drives.link_ok:
        trips.append(Trip("drive_link", FAIL, "Modbus link to the drives lost"))
    for which, st in (("spin", drives.spin), ("orbit", drives.orbit)):
        if st is not None and (st.fault_code or st.tripped):
            trips.append(Trip("drive_trip", FAIL, f"{which} drive tripped: fault {st.fault_code} {st.fault}".rstrip()))
    return trips


def _supply_trips(aux: AuxState, cfg: Interlocks, pressure_armed: bool) -> list[Trip]:
    if cfg.check_can_heartbeat and aux.node_lost:
        return [Trip("can_heartbeat", SUSPEND, "CAN sensor node lost (no heartbeat for 1.5 s)")]
    if not (pressure_armed and cfg.check_supply_pressure):
        return []
    trips = []
    if aux.pump_off:
        trips.append(Trip("supply_pump", SUSPEND, "lubricant supply pump is off"))
    p = aux.p_supply
    lo, hi = cfg.supply_pressure_min_mpa, cfg.supply_pressure_max_mpa
    if not aux.stale("p_supply") and not lo * MPA <= p <= hi * MPA:
        trips.append(
            Trip("supply_pressure", SUSPEND, f"supply pressure {p / MPA:.3f} MPa outside the band {lo:g}..{hi:g} MPa")
        )
    return trips
