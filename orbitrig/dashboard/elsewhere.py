"""Stop and abort from a page that shows another rig than its session watches now (another tab of
the same browser chose one): they go to the rig the page shows, the one the person looks at, when
it is a rig the dashboard knows (orbitrig.dashboard.commands.rig_for).

The session reads only the rig it watches, so the reply of such a stop or abort would come on a
topic it does not subscribe to. :class:`ElsewhereReplies` subscribes to that rig's reply topic
just before the command is published (without waiting for the broker's SUBACK: the broker reads
a connection's packets in order, so the reply cannot come before the subscription), and ends the
subscription once the reply came or the late-reply window is over; never one the session reads
for the rig it watches. A stop's or abort's reply awaited on the rig watched is kept the same way
should the session leave that rig before the reply comes (another tab chose another rig).
"""

from __future__ import annotations

import logging
from typing import Any

import orbitrig.service.protocol as proto

log = logging.getLogger("orbitrig.dashboard")

#: the outcome's words when the reply of another rig cannot be awaited
UNWATCHED = "its reply cannot be watched from this session: check that rig's state"


class ElsewhereReplies:
    """The reply topics of rigs the session does not watch, read while a reply on them is awaited."""

    def __init__(self) -> None:
        self._topics: dict[str, str] = {}  # correlation id -> reply topic

    def is_reply(self, topic: str) -> bool:
        """True for the reply topic of a rig whose stop's or abort's reply is awaited."""
        return topic in self._topics.values()

    def watch(self, client: Any, topics: proto.Topics, cid: str) -> bool:
        """Read the reply topic of ``topics`` for the command ``cid`` (to publish next); False: it cannot be read."""
        topic = topics.reply
        try:
            asked = topic in self._topics.values() or client.subscribe_nowait(topic, 1)
        except Exception as err:  # noqa: BLE001 - paho's errors: the command goes all the same
            log.info("reply topic %s not subscribed: %s", topic, err)
            asked = False
        if asked:
            self._topics[cid] = topic
        return asked

    def keep(self, topics: proto.Topics, cid: str) -> None:
        """The watched rig's reply topic (read already) stays read for ``cid``'s stop or abort should
        the session leave that rig before the reply comes."""
        self._topics[cid] = topics.reply

    def awaited(self) -> frozenset[str]:
        """The reply topics a reply is awaited on (a rig left keeps these subscribed)."""
        return frozenset(self._topics.values())

    def release(self, client: Any, cid: str, watched: proto.Topics) -> None:
        """The reply of ``cid`` came or is no longer awaited: its topic is read no more (unless still needed)."""
        topic = self._topics.pop(cid, None)
        if topic is None or topic == watched.reply or topic in self._topics.values() or client is None:
            return
        try:
            client.unsubscribe_nowait(topic)
        except Exception as err:  # noqa: BLE001 - the link went: a new connection subscribes afresh
            log.info("reply topic %s not unsubscribed: %s", topic, err)

    def resubscribe(self, client: Any) -> None:
        """A new broker connection, or a rig left (its topics unsubscribed): read again the reply topics
        still awaited."""
        for topic in set(self._topics.values()):
            try:
                client.subscribe_nowait(topic, 1)
            except Exception as err:  # noqa: BLE001 - the link went again: the next connection tries
                log.info("reply topic %s not subscribed again: %s", topic, err)
