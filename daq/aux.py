"""AuxSensors: the lubricant/supply sensor node on CAN (docs/protocols/can-node.md).

    async with AuxSensors("orbitrig-sim", interface="virtual") as aux:
        s = aux.latest()
        s.p_supply, s.beta, s.ages["p_supply"], s.stale("t_recess"), s.node_lost
        arrived = aux.arrival   # set by the next frame read: `await arrived.wait()`, then latest()

Frames are read on the event loop as they arrive (daq.can_reader; a bus without a file
descriptor, python-can's ``virtual``, by a thread that hands them over) and decoded there;
nothing blocks the loop. A bus whose link fails (an adapter pulled, the interface down, a
serial-over-TCP link closed) is said once, counts as the node lost at once (``link_error``)
and is opened again until it opens. Values
are kept in SI (K, Pa, m^3/s) with their arrival time; a value is stale when
its frame is older than 0.5 s (``ages``). ``bus_ages`` count from when the frame was on the bus: the
interface's receive timestamp (``can.Message.timestamp``, epoch s; python-can's ``virtual`` bus
stamps the send) where it lies within MAX_TRANSIT_S before the frame was read, else its arrival
(an interface whose timestamps count from elsewhere): a frame read after a moment but on the bus
before it (held by a busy loop, or by the thread that hands it over) is not taken for newer.
The node is lost when no heartbeat arrived for 1.5 s (counted from opening while none has come). A frame whose length is not
the spec's (0x180 + node id, 0x280 + node id: 8 bytes; 0x380 + node id: 4; 0x700 + node id: 1) is counted in
``frames_malformed`` and not read. `Frame` and `can_id_text` own the node's CAN ids: every message that names
one derives it from the node id (``[transports] can_node_id``). The heartbeats of other node ids pass the
bus filter too, only to name the nodes that answer when the configured one has not since the bus was
opened (``other_nodes``, `AuxState.others_heard`); they count as none of the node's frames.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import struct
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any
from dataclasses import dataclass, field
from enum import IntEnum

from daq.can_reader import CanReader
from daq.errors import DaqError

if TYPE_CHECKING:
    import can

STALE_AFTER = 0.5  # s
#: s a frame may plausibly have waited between the interface's timestamp and its reading; a
#: timestamp older (or in the future) counts from elsewhere, and the arrival stands for it
MAX_TRANSIT_S = 1.0
LOST_AFTER = 1.5  # s
HEARTBEAT_OPERATIONAL = 0x05
HEARTBEAT_PREOPERATIONAL = 0x7F
_KELVIN = 273.15
_LPM = 1e-3 / 60.0  # m^3/s per L/min


class Frame(IntEnum):
    """The node's frames by their function base: a frame's CAN id is its base plus the node id
    (`can_id_text`), docs/protocols/can-node.md."""

    TEMPERATURES = 0x180  # T_recess, T_groove, T_supply, flow
    PRESSURES = 0x280  # p_supply, p_recess 1..3
    STATUS = 0x380  # p_recess 4, status bits
    HEARTBEAT = 0x700


def can_id_text(frame: Frame, node_id: int) -> str:
    """`frame`'s CAN id for node `node_id`, as messages name it ('0x701' for the heartbeat of node 1)."""
    return f"0x{frame + node_id:03X}"


#: the heartbeats of every node id (0x700 + 1..127) pass the bus's filter: another node heard says why
#: the configured one is not (`others_heard_text`)
HEARTBEATS_MASK = 0x780


def others_heard_text(node_id: int, others: tuple[int, ...]) -> str:
    """'; heartbeat 0x701 heard (node 1), not node 5's 0x705 ([transports] can_node_id 5)' when the
    heartbeats of other nodes than `node_id` were read (node ids `others`), else ''."""
    if not others:
        return ""
    ids = ", ".join(can_id_text(Frame.HEARTBEAT, n) for n in others)
    nodes = ", ".join(str(n) for n in others)
    plural = "s" if len(others) > 1 else ""
    return (
        f"; heartbeat{plural} {ids} heard (node{plural} {nodes}), not node {node_id}'s "
        f"{can_id_text(Frame.HEARTBEAT, node_id)} ([transports] can_node_id {node_id})"
    )


# payload length of each frame, docs/protocols/can-node.md
_LENGTH: dict[int, int] = {Frame.TEMPERATURES: 8, Frame.PRESSURES: 8, Frame.STATUS: 4, Frame.HEARTBEAT: 1}
# value name -> the frame that carries it
_SOURCE = {
    "t_recess": Frame.TEMPERATURES,
    "t_groove": Frame.TEMPERATURES,
    "t_supply": Frame.TEMPERATURES,
    "flow": Frame.TEMPERATURES,
    "p_supply": Frame.PRESSURES,
    "p_recess": Frame.PRESSURES,  # p_recess 1..3 here, 4 in STATUS
    "sensor_fault": Frame.STATUS,
    "pump_off": Frame.STATUS,
}


@dataclass(frozen=True)
class AuxState:
    """Latest values in SI with their ages (s; inf when never received).

    t_recess, t_groove, t_supply (K); flow (m^3/s); p_supply (Pa); p_recess (4,) Pa;
    beta = mean recess pressure / p_supply (-); NaN for values never received.
    """

    t_recess: float = math.nan
    t_groove: float = math.nan
    t_supply: float = math.nan
    flow: float = math.nan
    p_supply: float = math.nan
    p_recess: tuple[float, float, float, float] = (math.nan,) * 4
    beta: float = math.nan
    sensor_fault: bool = False
    pump_off: bool = False
    heartbeat_state: int | None = None  # 0x05 operational, 0x7F pre-operational
    heartbeat_age: float = math.inf
    node_lost: bool = True
    ages: dict[str, float] = field(default_factory=dict)
    bus_ages: dict[str, float] = field(default_factory=dict)  # s since each value's frame was on the bus
    link_error: str | None = None  # why the bus is down (its link failed; being opened again): the node is lost
    node_id: int = 1  # the node read ([transports] can_node_id): its frames' CAN ids (`can_id`)
    other_nodes: tuple[int, ...] = ()  # ids of the other nodes whose heartbeat was read in the last 1.5 s

    @property
    def others_heard(self) -> str:
        """The other nodes heard on the bus instead, as messages append it (`others_heard_text`), while
        the node read has sent no heartbeat since the bus was opened (another node id than the one on
        the bus); '' once it has: a bus shared with other nodes names none of them when it is lost."""
        if not math.isinf(self.heartbeat_age):
            return ""
        return others_heard_text(self.node_id, self.other_nodes)

    def stale(self, name: str) -> bool:
        """True if value ``name`` is older than 0.5 s or never arrived."""
        return not self.ages.get(name, math.inf) <= STALE_AFTER

    def can_id(self, frame: Frame) -> str:
        """`frame`'s CAN id on the node read, as messages name it (`can_id_text`)."""
        return can_id_text(frame, self.node_id)

    @property
    def operational(self) -> bool:
        return not self.node_lost and self.heartbeat_state == HEARTBEAT_OPERATIONAL


class AuxSensors:
    """Async context manager reading the sensor node ``node_id`` on a python-can bus."""

    def __init__(
        self,
        channel: str,
        *,
        interface: str = "socketcan",
        bitrate: int = 500_000,
        node_id: int = 1,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.channel, self.interface, self.bitrate, self.node_id = channel, interface, bitrate, node_id
        self._clock = clock
        self._reader: CanReader | None = None  # once open (python-can imported when opened)
        self._values: dict[str, float] = {}
        self._times: dict[int, float] = {}  # CAN id offset -> arrival time
        self._on_bus: dict[int, float] = {}  # CAN id offset -> when that frame was on the bus (clock's time)
        self._p_recess = [math.nan] * 4
        self._heartbeat: int | None = None
        self._others: dict[int, float] = {}  # node id -> when a heartbeat of that other node was read
        self._opened_at = clock()
        self._arrival = asyncio.Event()  # set (and replaced) by each frame read
        self.frames_received = 0
        self.frames_malformed = 0

    async def __aenter__(self) -> AuxSensors:
        self.open()
        return self

    async def __aexit__(self, *exc: object) -> None:
        bus = self._close_reader()
        if bus is not None:  # off the loop: closing a serial-over-TCP bus (pyserial socket://) waits 0.3 s
            await asyncio.to_thread(bus.shutdown)

    def open(self) -> None:
        """Open the bus (in a running loop); raises DaqError naming the channel if it cannot.
        A bus that fails later is opened again until it opens (daq.can_reader)."""
        bus = self._open_bus()
        self._opened_at = self._clock()
        self._reader = CanReader(bus, self._open_bus, self._on_message, f"{self.interface}:{self.channel}")

    def _open_bus(self) -> can.BusABC:
        import can  # only the CAN reader needs python-can

        kwargs: dict[str, Any] = {} if self.interface == "virtual" else {"bitrate": self.bitrate}
        try:
            bus = can.Bus(interface=self.interface, channel=self.channel, **kwargs)
        except (can.CanError, OSError, ValueError, ImportError) as err:
            raise DaqError(f"CAN {self.interface}:{self.channel}: cannot open bus ({err})") from err
        filters: list[can.typechecking.CanFilter] = [
            {"can_id": frame + self.node_id, "can_mask": 0x7FF, "extended": False}
            for frame in Frame
            if frame != Frame.HEARTBEAT
        ]
        filters.append({"can_id": Frame.HEARTBEAT, "can_mask": HEARTBEATS_MASK, "extended": False})  # every node's
        try:
            bus.set_filters(filters)
        except (can.CanError, OSError, ValueError) as err:  # not left open: it is opened again and again
            bus.shutdown()
            raise DaqError(f"CAN {self.interface}:{self.channel}: cannot set the node's filters ({err})") from err
        return bus

    async def heard(self, within: float = LOST_AFTER) -> None:
        """Return once the node's heartbeat has been read (at once if it has); DaqError naming the
        bus and the heartbeat's CAN id if none is read within `within` s (wall): a bus that opens
        says nothing of the node (python-can's virtual bus opens any channel; a node off, another
        node id or bitrate leave a bus silent)."""
        loop = asyncio.get_running_loop()
        end = loop.time() + within
        while Frame.HEARTBEAT not in self._times:
            arrival, left = self.arrival, end - loop.time()
            if left <= 0:
                raise DaqError(self._unheard(within))
            with contextlib.suppress(TimeoutError):
                async with asyncio.timeout(left):  # not wait_for: in 3.11 it drops a cancel arriving with a frame
                    await arrival.wait()

    def _unheard(self, within: float) -> str:
        down = f"; the bus is down: {self.link_error}" if self.link_error else ""
        other = f"; {self.frames_received} other frames of the node read" if self.frames_received else ""
        instead = self.latest().others_heard
        hb = can_id_text(Frame.HEARTBEAT, self.node_id)
        return (
            f"CAN {self.interface}:{self.channel}: no heartbeat from node {self.node_id} (CAN id {hb}) within "
            f"{within:g} s{other}{instead}{down} (the node off or on another bus, or [transports] can_node_id "
            f"{self.node_id} or can_bitrate {self.bitrate} not the node's)"
        )

    @property
    def link_error(self) -> str | None:
        """Why the bus is down while it is (its link failed and is being opened again), else None."""
        return None if self._reader is None else self._reader.error

    @property
    def link_drops(self) -> int:
        """How often the bus failed and was opened again (or is being)."""
        return 0 if self._reader is None else self._reader.link_drops

    @property
    def arrival(self) -> asyncio.Event:
        """Set when the next frame is read (its values in `latest()` by then); each frame sets the
        event taken before it and puts a new one in its place: take it before looking at `latest()`."""
        return self._arrival

    def _close_reader(self) -> Any:
        reader, self._reader = self._reader, None
        return None if reader is None else reader.close()

    def close(self) -> None:
        """Idempotent."""
        bus = self._close_reader()
        if bus is not None:
            bus.shutdown()

    def _on_message(self, msg: can.Message) -> None:
        if msg.is_extended_id or msg.is_remote_frame or msg.is_error_frame:
            return
        kind = msg.arbitration_id - self.node_id
        data = bytes(msg.data)
        now = self._clock()
        other = msg.arbitration_id - Frame.HEARTBEAT
        if kind not in _LENGTH and msg.arbitration_id & HEARTBEATS_MASK == Frame.HEARTBEAT and other:
            self._others[other] = now  # another node's heartbeat (node ids 1..127)
            return
        if kind in _LENGTH and len(data) != _LENGTH[kind]:
            self.frames_malformed += 1  # not the spec's layout (8, 8, 4, 1 bytes): never misread
            return
        try:
            if kind == Frame.TEMPERATURES:
                tr, tg, ts, flow = struct.unpack_from("<hhhH", data)
                self._values.update(
                    t_recess=tr / 100 + _KELVIN,
                    t_groove=tg / 100 + _KELVIN,
                    t_supply=ts / 100 + _KELVIN,
                    flow=flow / 100 * _LPM,
                )
            elif kind == Frame.PRESSURES:
                ps, p1, p2, p3 = struct.unpack_from("<HHHH", data)
                self._values["p_supply"] = ps * 1e3
                self._p_recess[:3] = [p1 * 1e3, p2 * 1e3, p3 * 1e3]
            elif kind == Frame.STATUS:
                p4, status = struct.unpack_from("<HH", data)
                self._p_recess[3] = p4 * 1e3
                self._values.update(sensor_fault=bool(status & 1), pump_off=bool(status & 2))
            elif kind == Frame.HEARTBEAT:
                self._heartbeat = data[0]
            else:
                return
        except (struct.error, IndexError):
            self.frames_malformed += 1
            return
        self._times[kind] = now
        self._on_bus[kind] = now - _transit(msg)
        self.frames_received += 1
        arrival, self._arrival = self._arrival, asyncio.Event()
        arrival.set()

    def latest(self) -> AuxState:
        """Snapshot of the latest values, their ages and the node's liveness."""
        now = self._clock()
        ages, bus_ages = _ages(now, self._times), _ages(now, self._on_bus)
        v = self._values
        p_supply = float(v.get("p_supply", math.nan))
        p = self._p_recess
        p_recess = (p[0], p[1], p[2], p[3])
        beta = sum(p_recess) / 4 / p_supply if p_supply > 0 else math.nan
        heard = self._times.get(Frame.HEARTBEAT)
        hb_age = now - (-math.inf if heard is None else heard)
        return AuxState(
            t_recess=float(v.get("t_recess", math.nan)),
            t_groove=float(v.get("t_groove", math.nan)),
            t_supply=float(v.get("t_supply", math.nan)),
            flow=float(v.get("flow", math.nan)),
            p_supply=p_supply,
            p_recess=p_recess,
            beta=beta,
            sensor_fault=bool(v.get("sensor_fault", False)),
            pump_off=bool(v.get("pump_off", False)),
            heartbeat_state=self._heartbeat,
            heartbeat_age=hb_age,
            node_lost=self.link_error is not None or now - (self._opened_at if heard is None else heard) > LOST_AFTER,
            ages=ages,
            bus_ages=bus_ages,
            link_error=self.link_error,
            node_id=self.node_id,
            other_nodes=tuple(sorted(n for n, t in self._others.items() if now - t <= LOST_AFTER)),
        )


def _ages(now: float, times: dict[int, float]) -> dict[str, float]:
    """Each value's age (s; inf never received) from its frame's time in `times` (CAN id offset ->
    the clock's s): p_recess as old as the older of its two frames, beta as the older of p_recess
    and p_supply."""
    age = {k: now - t for k, t in times.items()}
    ages = {name: age.get(src, math.inf) for name, src in _SOURCE.items()}
    ages["p_recess"] = max(age.get(Frame.PRESSURES, math.inf), age.get(Frame.STATUS, math.inf))  # p_recess 4 in STATUS
    ages["beta"] = max(ages["p_recess"], ages["p_supply"])
    return ages


def _transit(msg: can.Message) -> float:
    """s between the interface's timestamp of `msg` and now, where plausible (0 to MAX_TRANSIT_S),
    else 0 (the arrival stands for it)."""
    transit = time.time() - msg.timestamp
    return transit if 0.0 <= transit <= MAX_TRANSIT_S else 0.0
