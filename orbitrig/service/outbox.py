"""The rig service's messages to the broker, in two lanes, each in order.

Replies to ordinary commands wait in a lane of their own, handed
over only when no status or result waits, and published beside them: a status
or a result never waits for the acknowledgements of a flood of replies (nor
they for its). Each lane sends ``PUBLISH_WINDOW`` messages at a time. What the
broker acknowledged is never sent again; what it had not when the link dropped
is sent again on the next connection (QoS 1 is at least once: a reply may come
twice, with its id).

:class:`Outbox` is the base of :class:`orbitrig.service.link.BrokerLink`: the link
connects and reads commands, its outbox publishes on each connection.
"""

from __future__ import annotations

import asyncio
import collections
import dataclasses
from collections.abc import Callable
from typing import Any

from orbitrig.service import broker_calls
from orbitrig.service import protocol as proto

#: messages handed to the MQTT client at once (it keeps its own in-flight limit)
PUBLISH_WINDOW = 64


@dataclasses.dataclass
class Outgoing:
    """One message waiting to go out."""

    topic: str
    payload: bytes
    qos: int
    retain: bool = False
    behind: bool = False  # a reply to an ordinary command: sent when nothing else waits


class Outbox:
    """The outgoing lanes of one rig service. ``first_status()`` gives the status sent first on
    every connection; ``online`` is set by the link while it is connected; ``drained`` is set
    while nothing waits to be sent or acknowledged."""

    def __init__(self, topics: proto.Topics, first_status: Callable[[], bytes]):
        self.topics, self._first_status = topics, first_status
        self._out: collections.deque[Outgoing] = collections.deque(maxlen=10_000)
        self._replies: collections.deque[Outgoing] = collections.deque()
        #: per lane (behind: replies), handed to the client, not yet acknowledged
        self._sending: dict[bool, list[Outgoing]] = {False: [], True: []}
        self._wakes = {False: asyncio.Event(), True: asyncio.Event()}  # per lane (behind: replies)
        self.drained = asyncio.Event()
        self.online = asyncio.Event()

    @property
    def reply_backlog(self) -> int:
        """Replies to ordinary commands not yet sent."""
        return len(self._replies)

    def send(self, topic: str, payload: bytes, qos: int, retain: bool = False, *, behind: bool = False) -> None:
        """Queue a message; ``behind``: a reply to an ordinary command (its own lane)."""
        if not self.online.is_set() and (qos == 0 or topic == self.topics.status):
            return  # progress is of no use later; the status is republished on connection
        if topic == self.topics.status and self._out and self._out[-1].payload == payload:
            return  # the same status waits to be sent already (a repeated "status" command)
        (self._replies if behind else self._out).append(Outgoing(topic, payload, qos, retain, behind))
        self.drained.clear()
        self._wakes[behind].set()

    @staticmethod
    def _next_batch(lane: collections.deque[Outgoing]) -> list[Outgoing]:
        batch: list[Outgoing] = []
        while lane and len(batch) < PUBLISH_WINDOW:
            batch.append(lane.popleft())
        return batch

    async def _publish_loop(self, client: Any) -> None:
        """Deliver the outgoing lanes, the current status first; what was handed over and
        not acknowledged when a link dropped goes again (what was acknowledged never)."""
        unsent = [m for lane in self._sending.values() for m in lane if m.topic != self.topics.status]
        pending = [m for m in self._out if m.topic != self.topics.status]
        self._out.clear()
        first = Outgoing(self.topics.status, self._first_status(), proto.QOS_STATUS, True)
        self._out.append(first)
        self._out.extend(m for m in unsent if not m.behind)
        self._out.extend(pending)
        self._replies.extendleft(reversed([m for m in unsent if m.behind]))
        self._sending = {False: [], True: []}
        async with asyncio.TaskGroup() as lanes:
            lanes.create_task(self._lane(client, behind=False), name="mqtt-publish-status")
            lanes.create_task(self._lane(client, behind=True), name="mqtt-publish-replies")

    async def _lane(self, client: Any, *, behind: bool) -> None:
        """One lane, PUBLISH_WINDOW messages at a time, each batch after the last one's
        acknowledgements. Replies (``behind``) are handed over only while no status or
        result waits; those never wait for the replies' acknowledgements."""
        queue, wake = (self._replies, self._wakes[True]) if behind else (self._out, self._wakes[False])
        while True:
            while self._sending[behind] or (queue and not (behind and self._out)):
                batch = self._sending[behind] = self._sending[behind] or self._next_batch(queue)
                if not behind and not self._out:
                    self._wakes[True].set()  # handed over in order: the replies' turn
                await asyncio.gather(*(self._publish(client, m, batch) for m in list(batch)))
                self._sending[behind] = []
            if not (self._out or self._replies or self._sending[False] or self._sending[True]):
                self.drained.set()
            wake.clear()
            await wake.wait()

    @staticmethod
    async def _publish(client: Any, m: Outgoing, batch: list[Outgoing]) -> None:
        await broker_calls.publish(client, m.topic, m.payload, qos=m.qos, retain=m.retain)
        batch.remove(m)  # acknowledged (QoS 1; QoS 0: written): never sent again
