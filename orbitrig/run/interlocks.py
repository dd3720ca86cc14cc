"""Interlocks: conditions that suspend or fail a run (pure, no I/O).

Like bluesky's suspenders: `check()` looks at the latest CAN sensor state and
drive state and returns the trips in force. A trip with action ``suspend``
holds the run until the condition clears (then the current block is settled
and acquired again); ``fail`` ends the run (both drives stopping). The
supervisor makes a suspension of a `TripKind` a fail once it has lasted its
limit (supervision.py).

| kind            | source                                            | action                   |
|-----------------|---------------------------------------------------|--------------------------|
| drive_trip      | a drive reports a fault (TRIPPED/FAULT)           | fail                     |
| drive_link      | the Modbus link to the drives is down             | fail                     |
| can_heartbeat   | no CAN heartbeat for 1.5 s (node lost)            | suspend, fail after      |
|                 |                                                   | can_heartbeat_timeout_s  |
| can_node        | node not operational, its pressure (0x280+id) or  | suspend, fail after      |
|                 | status (0x380+id) frame 1.5 s old, a sensor fault | can_heartbeat_timeout_s  |
| supply_pump     | the node reports the supply pump off              | suspend, fail after      |
|                 |                                                   | supply_lost_timeout_s    |
| supply_low      | p_supply below supply_pressure_min_mpa            | suspend, fail after      |
|                 |                                                   | supply_lost_timeout_s    |
| supply_pressure | p_supply above supply_pressure_max_mpa            | suspend                  |

The supply (can_node, supply_pump, supply_low) is watched whenever a drive
turns or the point's pressures are verified (`pressure_armed`); the band's
upper edge only once armed, as the operator may be adjusting the pressures.

Messages name the node's frames by the CAN ids of the node read (daq.aux.Frame, `AuxState.can_id`:
0x705 for the heartbeat of node 5), never node 1's.

A lost orbit trigger shows as an acquisition that gets no revolutions; the
engine retries it and then fails the run (it is not polled here).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum

from daq.aux import HEARTBEAT_OPERATIONAL, LOST_AFTER, AuxState, Frame
from drives.findings import trip_fault
from drives.state import LINK_LOST, RigDriveState
from orbitrig.config import MPA, Interlocks


class TripAction(StrEnum):
    """What a trip does to the run: hold it until the condition clears, or end it."""

    __repr__ = str.__repr__  # messages show 'suspend', as the plain string did

    SUSPEND = "suspend"
    FAIL = "fail"


SUSPEND, FAIL = TripAction


class TripKind(StrEnum):
    """What tripped. The CAN node's and the supply's suspensions become a fail once they last
    longer than their limit (NODE_KINDS, SUPPLY_KINDS)."""

    __repr__ = str.__repr__

    DRIVE_LINK = "drive_link"
    DRIVE_TRIP = "drive_trip"
    DRIVE_POLL = "drive_poll"  # a failure the drive poll recorded (a poll failed on a bug; a failed verification)
    CAN_HEARTBEAT = "can_heartbeat"
    CAN_NODE = "can_node"
    SUPPLY_PUMP = "supply_pump"
    SUPPLY_LOW = "supply_low"
    SUPPLY_HIGH = "supply_pressure"  # above the band once the point's pressures are verified
    SUPERVISION = "supervision"  # the supervisor itself failed: the interlocks are not watched
    RUN_HELPER = "run_helper"  # a helper task of the run failed (the message names it)
    INTERLOCK = "interlock"  # a suspension whose cause is no longer known


@dataclass(frozen=True)
class Trip:
    kind: TripKind
    action: TripAction
    message: str


#: the words of the CAN node lost (its trip's message: NODE_LOST (why))
NODE_LOST = "CAN sensor node lost"
#: s without any frame of the CAN node (5 of its 0.1 s process-data periods): it is said silent
SILENT_AFTER = 0.5
#: the CAN node gone or mute, and the supply itself lost: each group escalates on one clock
NODE_KINDS = frozenset({TripKind.CAN_HEARTBEAT, TripKind.CAN_NODE})
SUPPLY_KINDS = frozenset({TripKind.SUPPLY_PUMP, TripKind.SUPPLY_LOW})


def check(aux: AuxState | None, drives: RigDriveState | None, cfg: Interlocks, *, pressure_armed: bool) -> list[Trip]:
    """Trips in force given the latest CAN sensor state `aux` and drive state `drives` (either may be None).
    The supply is watched while a drive turns or once `pressure_armed` (the point's pressures were
    verified); the band's upper edge only once armed."""
    trips = _drive_trips(drives) if drives is not None else []
    if aux is not None:
        trips += _supply_trips(aux, cfg, pressure_armed, _turning(drives))
    return trips


def _turning(drives: RigDriveState | None) -> bool:
    """A drive reads a speed other than zero (unknown speeds count as turning once read at all)."""
    return drives is not None and (drives.spin is not None or drives.orbit is not None) and not drives.stopped


def _drive_trips(drives: RigDriveState) -> list[Trip]:
    trips = []
    if not drives.link_ok:
        why = f" ({drives.link_error})" if drives.link_error else ""  # the drive and request that went unanswered
        trips.append(Trip(TripKind.DRIVE_LINK, FAIL, LINK_LOST + why))
    for st in (drives.spin, drives.orbit):
        if st is not None and (st.fault_code or st.tripped):
            trips.append(Trip(TripKind.DRIVE_TRIP, FAIL, str(trip_fault(st))))  # named as every drive error is
    return trips


def _node_missing(aux: AuxState, cfg: Interlocks) -> str | None:
    """What the CAN node does not give that the supply watch needs, or None."""
    if cfg.check_can_heartbeat and aux.heartbeat_state not in (None, HEARTBEAT_OPERATIONAL):
        hb = aux.can_id(Frame.HEARTBEAT)
        return f"CAN sensor node not operational (heartbeat {hb} state {aux.heartbeat_state:#04x})"
    if not cfg.check_supply_pressure:
        return None
    for name, what, frame in (("p_supply", "pressure", Frame.PRESSURES), ("pump_off", "status", Frame.STATUS)):
        age = aux.ages.get(name, math.inf)
        if not age <= LOST_AFTER:  # as long as a heartbeat may be missed: a busy host's hiccup is no trip
            return f"CAN sensor node sends no {what} frame {aux.can_id(frame)} (last {age:.1f} s ago)"
    if aux.sensor_fault:
        return f"CAN sensor node reports a faulty sensor (status {aux.can_id(Frame.STATUS)} bit 0)"
    return None


def _why_lost(aux: AuxState) -> str:
    """Why the CAN node counts as lost, naming its heartbeat's CAN id: its bus link failed, it fell
    silent altogether (no process data either for SILENT_AFTER s and more: said with how long), or its
    heartbeat alone is missing; and the other nodes heard on the bus instead (another node id)."""
    hb = aux.can_id(Frame.HEARTBEAT)
    if aux.link_error:
        return f"its bus link failed: {aux.link_error}"
    quiet = min([aux.heartbeat_age, *aux.ages.values()])
    if math.isinf(quiet):
        why = f"silent: no frame from node {aux.node_id} (heartbeat {hb}) since the bus was opened"
    elif quiet > SILENT_AFTER:
        why = f"silent: no heartbeat {hb} and no process data for {quiet:.1f} s"
    else:
        why = f"no heartbeat {hb} for {LOST_AFTER:g} s"
    return why + aux.others_heard


def _supply_trips(aux: AuxState, cfg: Interlocks, pressure_armed: bool, turning: bool) -> list[Trip]:
    if cfg.check_can_heartbeat and aux.node_lost:
        return [Trip(TripKind.CAN_HEARTBEAT, SUSPEND, f"{NODE_LOST} ({_why_lost(aux)})")]
    if not (pressure_armed or turning):
        return []
    missing = _node_missing(aux, cfg)
    if missing is not None:
        return [Trip(TripKind.CAN_NODE, SUSPEND, f"supply pressure and pump not watched: {missing}")]
    if not cfg.check_supply_pressure:
        return []
    trips = []
    if aux.pump_off:
        trips.append(Trip(TripKind.SUPPLY_PUMP, SUSPEND, "lubricant supply pump is off"))
    p = aux.p_supply
    lo, hi = cfg.supply_pressure_min_mpa, cfg.supply_pressure_max_mpa
    band = f"supply pressure {p / MPA:.3f} MPa outside the band {lo:g}..{hi:g} MPa"
    if not p >= lo * MPA:
        trips.append(Trip(TripKind.SUPPLY_LOW, SUSPEND, band))
    elif pressure_armed and p > hi * MPA:
        trips.append(Trip(TripKind.SUPPLY_HIGH, SUSPEND, band))
    return trips
